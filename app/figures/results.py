"""Figures straight from finished sweeps: several :class:`~qsid_core.SweepResult` on one plotly figure.

The engine stays free of plotting; this module turns results (fresh, loaded by
:func:`qsid_core.load_result`, their ``to_dict()`` JSON, or the path of a saved
``qsid sweep --out`` file) into the per-b rows the dashboard's view builders
draw, and calls those builders:

``error``
    relative errors of A and B against b, Theorem 1's line for every series
    whose prediction differs (:func:`app.figures.error_vs_bits.error_figure`);
``cost``
    closed-loop MPC cost on the true plant, with each result's true-model cost;
``stabilized``
    share of closed loops that converge (95 % Wilson interval) and the cost gap
    and the word lengths from which the MPC stabilizes, the small-gain certificate
    holds and the letter's bound says something
    (:func:`app.figures.bits_needed.bits_figure`, as ``qsid bits``);
``bound``
    the letter's ultimate bound delta(eps), the a-posteriori bound and the final
    state norms.

A nonlinear plant's panels of ``qsid reproduce`` (:func:`lifted_panels`) are drawn from its staged study by the
same view builders.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np
import plotly.graph_objects as go

if TYPE_CHECKING:
    from qsid_core import SweepResult
    from qsid_core.studies import KoopmanExperiment

#: What the functions take as one result: a SweepResult, its ``to_dict()``, or the path of a saved one.
ResultLike: TypeAlias = "SweepResult | dict[str, Any] | str | Path"

__all__ = ["plot_results", "result_series", "lifted_panels", "FigureError", "LIFTED_LABELS", "VIEWS"]

#: Estimator -> the label of its series in a nonlinear plant's figures.
LIFTED_LABELS = {"ls": "LS", "bcls": "BCLS"}

#: The views :func:`plot_results` draws.
VIEWS = ("error", "cost", "stabilized", "bound")
#: Settings that tell results apart in automatic labels, in the order they are named.
_LABEL_KEYS = (
    "system",
    "estimator",
    "dither",
    "input_bits",
    "state_bits",
    "noise",
    "noise_known",
    "range",
    "guard",
    "trajectories",
    "steps",
    "realizations",
    "input_amplitude",
    "data_seed",
    "dither_seed",
)


class FigureError(ValueError):
    """A bad argument to a figure function (the message names it)."""


def _as_dict(result: ResultLike, k: int) -> dict[str, Any]:
    """The JSON of one result: a SweepResult, its ``to_dict()``, or the path of a saved one."""
    if isinstance(result, (str, Path)):
        from qsid_core import load_result

        return load_result(result).to_dict()
    if hasattr(result, "to_dict") and hasattr(result, "bits"):
        return result.to_dict()
    if isinstance(result, dict) and isinstance(result.get("results"), list):
        return result
    raise FigureError(
        f"results[{k}]: expected a SweepResult, its to_dict() or the path of a saved result; "
        f"got {type(result).__name__}"
    )


def _setting(d: dict[str, Any], key: str) -> Any:
    if key == "system":
        return d.get("system")
    v = (d.get("config") or {}).get(key)
    return tuple(v) if isinstance(v, list) else v


def _auto_labels(dicts: list[dict[str, Any]]) -> list[str]:
    """'LS' / 'BCLS' for one result; else the estimator plus every setting that differs between results."""
    differ = [k for k in _LABEL_KEYS if k != "estimator" and len({repr(_setting(d, k)) for d in dicts}) > 1]
    out = []
    for d in dicts:
        est = str(_setting(d, "estimator") or "ls").upper()
        parts = []
        for k in differ:
            v = _setting(d, k)
            v = ",".join(map(str, v)) if isinstance(v, tuple) else ("default" if v is None else v)
            parts.append(str(v) if k == "system" else f"{k.replace('_', ' ')} {v}")
        out.append(", ".join([est, *parts]))
    return out


def result_series(
    *results: ResultLike, labels: Sequence[str] | None = None
) -> tuple[dict[str, list[dict[str, Any]]], list[dict[str, Any]]]:
    """``({label: rows}, [result JSON, ...])`` of the results, in order (the rows the view builders draw).

    Raises
    ------
    FigureError
        No results, a result of another type, labels of the wrong number or repeated.
    """
    if not results:
        raise FigureError("results: give at least one SweepResult")
    dicts = [_as_dict(r, k) for k, r in enumerate(results)]
    if labels is None:
        labels = _auto_labels(dicts)
        if len(set(labels)) < len(labels):  # the same settings twice: number them
            labels = [f"{lab} #{k + 1}" for k, lab in enumerate(labels)]
    else:
        labels = [str(lab) for lab in labels]
        if len(labels) != len(dicts):
            raise FigureError(f"labels: {len(labels)} labels for {len(dicts)} results; give one per result")
        if len(set(labels)) < len(labels):
            raise FigureError(f"labels: every label must be different; got {labels}")
    return dict(zip(labels, (d["results"] for d in dicts))), dicts


def _stabilized(
    series: dict[str, list[dict[str, Any]]], dicts: list[dict[str, Any]], height: int, results: Sequence[Any] = ()
) -> go.Figure:
    """The bits view; the small-gain test of Theorem 1's predicted model is recomputed from each result's
    configuration (its data are simulated again; no closed loop runs); each loop's own test where a fresh
    result still holds its models and loops (a loaded one does not)."""
    from qsid_core import Experiment, SweepConfig
    from qsid_core.control import data_rate_bits
    from qsid_core.studies import answer_from_rows, predicted_small_gains, realized_small_gain

    from .bits_needed import bits_figure

    answers = {}
    fresh = list(results) + [None] * (len(dicts) - len(results))
    for (label, rows), d, res in zip(series.items(), dicts, fresh):
        if not any(r.get("closed_loop_outcomes") for r in rows):
            raise FigureError(f"view 'stabilized': the result {label!r} has no closed loops (it ran without MPC)")
        ex = Experiment(SweepConfig.from_dict(d["config"]))
        robust = predicted_small_gains(ex, [int(r["bits"]) for r in rows])
        A = np.asarray(d["config"]["system_definition"]["A"], dtype=float)
        own = None
        if getattr(res, "loops", None) and getattr(res, "identification", None):
            s = res.system
            own = {b: int(realized_small_gain(res.identification[b], res.loops[b], s.A, s.B).sum()) for b in res.loops}
        answers[label] = answer_from_rows(
            d.get("system", ""),
            {},
            rows,
            d.get("mpc_cost_true_model"),
            robust=robust,
            robust_realized=own,
            data_rate=data_rate_bits(A),
        )
    return bits_figure(answers, height=height)


def plot_results(
    *results: ResultLike, view: str = "error", labels: Sequence[str] | None = None, height: int | None = None
) -> go.Figure:
    """One plotly figure of several sweep results.

    Parameters
    ----------
    *results : SweepResult, dict or path
        Fresh results of :func:`qsid_core.run_sweep`, results read back by
        :func:`qsid_core.load_result`, their ``to_dict()``, or paths of saved JSON results.
    view : {"error", "cost", "stabilized", "bound"}
        What to draw (see the module docstring).
    labels : sequence of str, optional
        One legend label per result (default: the estimator and the settings that differ).
    height : int, optional
        Figure height in pixels (default: the view's own).

    Returns
    -------
    plotly.graph_objects.Figure

    Raises
    ------
    FigureError
        An unknown view, bad labels, or a view the results cannot give (``cost`` and
        ``stabilized`` need closed loops).
    """
    if view not in VIEWS:
        raise FigureError(f"view: {view!r} is not one of {', '.join(VIEWS)}")
    series, dicts = result_series(*results, labels=labels)
    bcls = [lab for lab, d in zip(series, dicts) if d["config"].get("estimator") == "bcls"]
    if view == "error":
        from .error_vs_bits import error_figure

        return error_figure(series, height=height or 380, theory_per_series=True, bcls=bcls)
    if view == "stabilized":
        return _stabilized(series, dicts, height or 480, results)
    if view == "cost":
        from .cost import cost_figure

        for label, rows in series.items():
            if not any(r.get("mpc_cost") for r in rows):
                raise FigureError(f"view 'cost': the result {label!r} has no MPC cost (it ran without MPC)")
        more = [(lab, d.get("mpc_cost_true_model")) for lab, d in list(zip(series, dicts))[1:]]
        return cost_figure(series, true_cost=dicts[0].get("mpc_cost_true_model"), height=height or 380, more_true=more)
    from .bound import bound_figure

    mpc = dicts[0]["config"].get("mpc") or {}
    x0 = dicts[0]["config"]["system_definition"].get("x0")
    return bound_figure(
        series,
        theory_per_series=True,
        height=height or 400,
        steps=mpc.get("steps"),
        x0_norm=float(np.linalg.norm(x0)) if x0 else None,
    )


def _lifted_portrait(ex: KoopmanExperiment, b: int, tag: str) -> go.Figure:
    from .palette import COLORS, color
    from .phase_portrait import phase_portrait_figure

    s = ex.system
    ref = ex.reference_loop()
    loops = {lab: ex.loops(b, e) for e, lab in LIFTED_LABELS.items()}
    first = loops["LS"]
    assert first is not None and ref is not None
    fig = phase_portrait_figure(
        first.states,
        ref.states[0],
        dims=(0, 1, None),
        names=s.state_names,
        title=f"({tag}) the plant's flow (green) and the Koopman MPC loops at b = {b} (x1, x2, step k)",
        label="LS",
    )
    for tr in fig.data:  # the linear portrait's names, said for the lifted models
        if tr.name and tr.name.endswith("realizations"):
            tr.name = f"LS ({first.states.shape[0]} loops)"
        elif tr.name == "true model":
            tr.name = "unquantized EDMD"
    bc = loops["BCLS"]
    assert bc is not None
    for k, st in enumerate(bc.states):
        ok = np.all(np.isfinite(st), axis=1)
        fig.add_scatter3d(
            x=st[ok, 0], y=st[ok, 1], z=np.arange(st.shape[0])[ok], mode="lines", name="BCLS", legendgroup="BCLS",
            showlegend=k == 0, line=dict(color=color("BCLS"), width=2),
        )  # fmt: skip
    for k, st in enumerate(ex.free_flow(first.states.shape[1] - 1)):
        ok = np.all(np.isfinite(st), axis=1)
        fig.add_scatter3d(
            x=st[ok, 0], y=st[ok, 1], z=np.arange(st.shape[0])[ok], mode="lines", name="free flow (u = 0)",
            legendgroup="flow", showlegend=k == 0, line=dict(color=COLORS["theory"], width=1.5),
        )  # fmt: skip
    return fig


def lifted_panels(
    ex: KoopmanExperiment, rows: dict[str, list[dict[str, Any]]], eigen_bits: int, portrait_bits: Sequence[int]
) -> list[tuple[str, go.Figure]]:
    """``qsid reproduce``'s panels of a nonlinear plant from its staged study ``ex`` and the rows of LS and BCLS:
    (a) the error of [A_z, B_z] vs b, (b) the prediction error, (c) the Koopman MPC outcomes, (d) the
    eigenvalues of A_z at ``eigen_bits``, (e)... the plant's flow and the loops at each of ``portrait_bits``."""
    from .eigenvalues import eigen_figure, lifted_eigenvalues
    from .error_vs_bits import lifted_error_figure
    from .loop_outcomes import outcomes_figure
    from .prediction_error import prediction_figure

    R, s = ex.config.realizations, ex.system.name
    fa = lifted_error_figure(rows, None, ex.config.quantizer.guard, height=460)
    fa.update_layout(
        title=dict(text=f"(a) {s}: error of [A_z, B_z] vs the unquantized EDMD (mean ± std, {R} realizations)")
    )
    fb = prediction_figure(rows, None, ex.reference()[1], ex.horizon, height=420)
    fb.update_layout(
        title=dict(text=f"(b) prediction error over steps 1..{ex.horizon} from each held-out run's start"),
        margin=dict(t=60),
    )
    fc = outcomes_figure(rows, None, height=420)
    fc.update_layout(
        title=dict(text=f"(c) Koopman MPC on the true plant, share of {R} loops per b (LS left · BCLS right)")
    )
    eigs = {lab: lifted_eigenvalues(ex.models(eigen_bits, e).models) for e, lab in LIFTED_LABELS.items()}
    fd = eigen_figure(eigs, np.linalg.eigvals(ex.reference()[0].A), height=460)
    fd.data[1].name = "unquantized EDMD"
    fd.update_layout(title=dict(text=f"(d) eigenvalues of A_z at b = {eigen_bits}"), margin=dict(t=60))
    out = [("a_error", fa), ("b_prediction", fb), ("c_outcomes", fc), ("d_eigenvalues", fd)]
    return out + [(f"{t}_phase_b{b}", _lifted_portrait(ex, b, t)) for t, b in zip("efg", portrait_bits)]
