"""View: x_i(t) and u_j(t) of the closed loops at the current b (true model, LS, BCLS), input bounds drawn.

The arrays come from :func:`qsid_core.control.timeseries.time_series`; this module only
draws them. With few realizations every loop is a thin line; with more than
:data:`MAX_LINES` the mean and a mean +- std band are drawn instead.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import plotly.graph_objects as go
from numpy.typing import NDArray

from qsid_core import TimeSeries, time_series

from .palette import COLORS, color
from .raw import arr, figure, hline, stacked_axes
from .view import CURRENT, FrameView, View

if TYPE_CHECKING:
    from collections.abc import Sequence

    from qsid_core import ClosedLoops

__all__ = ["time_series_figure", "VIEW", "MAX_LINES"]

#: More realizations than this: mean +- std band instead of one line per loop.
MAX_LINES = 8


def _lines(
    t: NDArray[np.float64],
    Y: NDArray[np.float64],
    ok: NDArray[np.bool_],
    c: str,
    name: str,
    yaxis: str,
    legend: bool,
) -> list[dict[str, Any]]:
    """One trace holding every successful loop (NaN-separated: one plotly trace, not R)."""
    Y = Y[ok]
    if Y.shape[0] == 0:
        return []
    gap = np.full((Y.shape[0], 1), np.nan)
    xs = np.hstack([np.broadcast_to(t, Y.shape), gap]).reshape(-1)
    ys = np.hstack([Y, gap]).reshape(-1)
    return [
        dict(
            type="scatter",
            x=arr(xs),
            y=arr(ys),
            mode="lines",
            name=name,
            legendgroup=name,
            showlegend=legend,
            line=dict(color=c, width=1),
            opacity=0.55,
            xaxis="x",
            yaxis=yaxis,
        )
    ]


def _band(
    t: NDArray[np.float64],
    m: NDArray[np.float64],
    s: NDArray[np.float64],
    c: str,
    name: str,
    yaxis: str,
    legend: bool,
) -> list[dict[str, Any]]:
    if not np.all(np.isfinite(m)):
        return []
    return [
        dict(
            type="scatter",
            x=arr(np.concatenate([t, t[::-1]])),
            y=arr(np.concatenate([m + s, (m - s)[::-1]])),
            fill="toself",
            fillcolor=c,
            opacity=0.18,
            line=dict(width=0),
            hoverinfo="skip",
            showlegend=False,
            legendgroup=name,
            xaxis="x",
            yaxis=yaxis,
        ),
        dict(
            type="scatter",
            x=arr(t),
            y=arr(m),
            mode="lines",
            name=f"{name} mean ± std",
            legendgroup=name,
            showlegend=legend,
            line=dict(color=c, width=1.5),
            xaxis="x",
            yaxis=yaxis,
        ),
    ]


def _channel(
    ts: TimeSeries, k: int, n: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(t, every loop (R, T), mean, std) of channel k (states first, then inputs)."""
    if k < n:
        return ts.t, ts.states[..., k], ts.state_mean[:, k], ts.state_std[:, k]
    return ts.t[:-1], ts.inputs[..., k - n], ts.input_mean[:, k - n], ts.input_std[:, k - n]


def time_series_figure(
    series: dict[str, TimeSeries],
    true: TimeSeries | None,
    state_names: Sequence[str],
    input_names: Sequence[str],
    x_ref: NDArray[np.float64] | None = None,
    x_max: NDArray[np.float64] | None = None,
    height: int = 520,
    title: str = "",
) -> go.Figure:
    """One subplot per state, then one per input, over one shared time axis.

    Parameters
    ----------
    series : dict label -> TimeSeries
        Closed loops of the identified models (``states`` (R, T+1, n), ``inputs`` (R, T, m)).
    true : TimeSeries or None
        The MPC built on the true model (one loop), drawn black.
    x_ref, x_max : array (n,) or None
        Reference (dotted, green; a time-varying one, shape (T+1, n), as a dashed path) and state
        box (dashed) drawn on the state rows; input bounds
        (``TimeSeries.u_max``) dashed on the input rows.
    """
    n, m = len(state_names), len(input_names)
    layout, yax = stacked_axes(n + m, x_title="closed-loop step t")
    data: list[dict[str, Any]] = []
    shapes: list[dict[str, Any]] = []
    for i, (label, ts) in enumerate(series.items()):
        c, many = color(label, i), int(ts.ok.sum()) > MAX_LINES
        for k in range(n + m):
            t, Y, mean, std = _channel(ts, k, n)
            data += (
                _band(t, mean, std, c, label, yax[k], k == 0) if many else _lines(t, Y, ts.ok, c, label, yax[k], k == 0)
            )
    if true is not None and true.ok.any():
        for k in range(n + m):
            t, Y, _, _ = _channel(true, k, n)
            data.append(
                dict(
                    type="scatter",
                    x=arr(t),
                    y=arr(Y[0]),
                    mode="lines",
                    name="true model",
                    legendgroup="true",
                    showlegend=k == 0,
                    line=dict(color=COLORS["true"], width=1.5),
                    xaxis="x",
                    yaxis=yax[k],
                )
            )
    umax = next((ts.u_max for ts in series.values() if ts.u_max is not None), None)
    for j in range(m):
        if umax is not None and np.isfinite(umax[j]):
            shapes += [hline(s * float(umax[j]), yax[n + j], COLORS["ref"]) for s in (1, -1)]
    ref_traces, ref_shapes = _state_marks(x_ref, x_max, yax[:n])
    data += ref_traces
    shapes += ref_shapes
    names = [f"x: {s}" for s in state_names] + [f"u: {u}" for u in input_names]
    for k, nm in enumerate(names):
        layout["yaxis" if k == 0 else f"yaxis{k + 1}"]["title"] = dict(text=nm, font=dict(size=10))
    layout.update(
        height=height,
        shapes=shapes,
        margin=dict(l=60, r=10, t=30 + 14 * title.count("<br>") if title else 10, b=40),
        legend=dict(orientation="h", y=-0.12),
    )
    if title:
        layout["title"] = dict(text=title, font=dict(size=12))
    return figure(data, layout)


def _state_marks(
    x_ref: NDArray[np.float64] | None, x_max: NDArray[np.float64] | None, yaxes: Sequence[str]
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """``(traces, shapes)`` on the state rows ``yaxes``: the reference (a time-varying one, shape (T+1, n), as a
    dashed path; a constant one, shape (n,), dotted) and the state box ``x_max`` (dashed)."""
    data: list[dict[str, Any]] = []
    shapes: list[dict[str, Any]] = []
    ref = None if x_ref is None else np.asarray(x_ref, dtype=float)
    for k, ya in enumerate(yaxes):
        if ref is not None and ref.ndim == 2 and np.any(ref[:, k] != 0):  # time-varying: the path, dashed
            data.append(
                dict(
                    type="scatter",
                    x=list(range(ref.shape[0])),
                    y=arr(ref[:, k]),
                    mode="lines",
                    name="reference",
                    legendgroup="ref",
                    showlegend=k == 0,
                    xaxis="x",
                    yaxis=ya,
                    line=dict(color=COLORS["theory"], dash="dash", width=2),
                )
            )
        elif ref is not None and ref.ndim == 1 and ref[k] != 0:
            shapes.append(hline(float(ref[k]), ya, COLORS["theory"], dash="dot"))
        if x_max is not None and np.isfinite(x_max[k]):
            shapes += [hline(s * float(x_max[k]), ya, COLORS["ref"]) for s in (1, -1)]
    return data, shapes


def mpc_arrays(frame: FrameView) -> dict[str, Any]:
    """The frame's MPC settings as arrays (``u_max``, ``x_ref``, ``x_max``; empty without an MPC)."""
    mpc = frame.ex.config.mpc if frame.ex is not None else None
    if mpc is None:
        return {}
    w = mpc.resolve(frame.system)  # MPCWeights
    ref = w.x_ref if w.reference is None else w.reference[: mpc.steps + 1]
    return {"u_max": w.u_max, "x_ref": ref, "x_max": w.x_max}


def loop_series(frame: FrameView) -> tuple[dict[str, TimeSeries], TimeSeries | None]:
    """The frame's closed loops at the current b as :class:`~qsid_core.control.timeseries.TimeSeries` (label -> ts, true)."""
    u_max = mpc_arrays(frame).get("u_max")
    ts = {lab: time_series(frame.loops[lab], frame.x0, u_max) for lab in frame.labels}
    true = time_series(frame.true_loop, frame.x0, u_max) if frame.true_loop is not None else None
    return ts, true


def saturation_text(ts: dict[str, TimeSeries]) -> str:
    """'LS 12 steps in 3/20 loops, BCLS ...' (steps with an input on its bound)."""
    return ", ".join(
        f"{lab} {s.saturated_steps} steps in {s.saturated_loops}/{len(s.ok)} loops" for lab, s in ts.items()
    )


def failure_text(loops: dict[str, ClosedLoops]) -> str:
    """'LS 5/5 failed (infeasible; not drawn)' and 'LS 48/50 did not converge (48 bounded)' per estimator
    ('' if every loop converged): failed loops are not drawn, loops that did not converge are."""
    out: list[str] = []
    for lab, lp in loops.items():
        kinds = [str(getattr(f, "value", f)) for f in lp.failure if f]
        if kinds:
            out.append(f"{lab} {len(kinds)}/{len(lp.failure)} failed ({', '.join(sorted(set(kinds)))}; not drawn)")
        oc = lp.outcome_counts()
        stuck = {k: oc[k] for k in ("bounded", "diverged") if oc.get(k)}
        if stuck and sum(stuck.values()) > len(kinds):
            out.append(
                f"{lab} {len(lp.outcome) - oc['converged']}/{len(lp.outcome)} did not converge on the true "
                f"plant ({', '.join(f'{v} {k}' for k, v in stuck.items())})"
            )
    return ", ".join(out)


def _build(frame: FrameView) -> go.Figure:
    ts, true = loop_series(frame)
    rm = mpc_arrays(frame)
    x_ref, x_max = rm.get("x_ref"), rm.get("x_max")
    rows = len(frame.system.state_names) + len(frame.system.input_names)
    failed = failure_text({lab: frame.loops[lab] for lab in frame.labels})
    return time_series_figure(
        ts,
        true,
        frame.system.state_names,
        frame.system.input_names,
        x_ref,
        x_max,
        height=110 * rows + 90,
        title=f"closed loops at b = {frame.bits} · saturated: {saturation_text(ts)}"
        + (f"<br>{failed}" if failed else ""),
    )


def _key(frame: FrameView) -> tuple[int, tuple[int, ...], int]:
    return (frame.bits, tuple(id(frame.loops[lab]) for lab in frame.labels), id(frame.true_loop))


VIEW = View("timeseries", aspect=1.25, depends=CURRENT, build=_build, tab="Control", key=_key)
