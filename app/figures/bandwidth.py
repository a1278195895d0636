"""View: a link of limited bandwidth. At a fixed budget of bits, the model error and the stabilized share against
the word length b, noise-free and with the sensor noise side by side, the knee marked.

The numbers are :func:`qsid_core.studies.bandwidth`'s (two :class:`~qsid_core.studies.BudgetResult` s, their
``to_dict()``), which the tab's :class:`~qsid_core.studies.Study` computes after the curves when the "bit budget"
setting is not 0. Left: ``err_G`` (mean ± std over the realizations, log) against b, noise-free (black) and with
the noise (orange), the prediction dashed (linear plants), each curve's knee (the smallest b within 25 % of its
least error) marked by a vertical line and named in the legend. Right: the share of the loops that converge on
the true plant against b (a nonlinear plant's: converged, and dotted within the convergence radius).
"""

from __future__ import annotations

import textwrap
from typing import Any

import numpy as np
import plotly.graph_objects as go

from .raw import arr, figure
from .view import CURVES, FrameView, View

__all__ = ["bandwidth_figure", "VIEW", "KOOPMAN_VIEW", "SIDES"]

#: The two sides: key of :class:`~qsid_core.studies.Bandwidth`, legend name, colour.
SIDES = (("noise_free", "noise-free", "#000000"), ("noisy", "with noise", "#ff7f0e"))
#: The prediction's colour of each side's (a lighter or darker shade: visible where it lies on the measurement).
PREDICTED = {"#000000": "#7f7f7f", "#ff7f0e": "#8c564b"}


def _mean(rows: list[dict[str, Any]], key: str) -> np.ndarray:
    return arr([np.nan if r.get(key) is None else r[key] for r in rows])


def _side(d: dict[str, Any], name: str, col: str) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Traces and knee line of one budget result ``d`` (``BudgetResult.to_dict()``)."""
    rows = [r for r in d["rows"] if r["identifiable"]]
    b = arr([r["bits"] for r in rows])
    m = arr([r["err_G"]["mean"] for r in rows])
    s = arr([r["err_G"]["std"] for r in rows])
    knee = d.get("b_knee")
    data: list[dict[str, Any]] = [
        dict(
            type="scatter", x=b, y=m, mode="lines+markers", name=f"{name}: err_G (knee b = {knee})",
            legendgroup=name, line=dict(color=col), marker=dict(size=5),
            error_y=dict(type="data", array=s, visible=True, color=col, thickness=1),
            xaxis="x", yaxis="y",
        ),
    ]  # fmt: skip
    if not d["nonlinear"] and any(r.get("predicted_err_G") is not None for r in rows):
        data.append(
            dict(
                type="scatter", x=b, y=_mean(rows, "predicted_err_G"), mode="lines",
                name=f"{name}: predicted (knee b = {d.get('b_knee_predicted')})", legendgroup=name,
                line=dict(color=PREDICTED[col], dash="dash", width=2), xaxis="x", yaxis="y",
            )
        )  # fmt: skip
    if d["config"]["mpc"]:
        data.append(
            dict(
                type="scatter", x=b, y=_mean(rows, "stabilized_fraction"), mode="lines+markers",
                name=f"{name}: stabilized", legendgroup=name, showlegend=False, line=dict(color=col),
                xaxis="x2", yaxis="y2",
            )
        )  # fmt: skip
        if d["nonlinear"]:
            n = arr([sum((r.get("closed_loop_outcomes") or {}).values()) or np.nan for r in rows])
            data.append(
                dict(
                    type="scatter", x=b, y=_mean(rows, "within_radius") / n, mode="lines",
                    name="within radius", legendgroup=name, line=dict(color=col, dash="dot"),
                    xaxis="x2", yaxis="y2",
                )
            )  # fmt: skip
    shapes = []
    if knee is not None:
        shapes.append(
            dict(
                type="line", xref="x", yref="y domain", x0=knee, x1=knee, y0=0, y1=1, name=f"knee {name}",
                line=dict(color=col, dash="dot", width=1.5),
            )
        )  # fmt: skip
    return data, shapes


def bandwidth_figure(result: Any, height: int = 360, note: str = "") -> go.Figure:
    """The bandwidth view of ``result`` (a :class:`~qsid_core.studies.Bandwidth`, or None: not computed)."""
    layout: dict[str, Any] = dict(
        xaxis=dict(domain=[0, 0.5], title=dict(text="word length b (bits)"), anchor="y", dtick=2),
        xaxis2=dict(domain=[0.66, 1], title=dict(text="word length b (bits)"), anchor="y2", dtick=2),
        yaxis=dict(type="log", anchor="x", title=dict(text="err_G"), exponentformat="power"),
        yaxis2=dict(anchor="x2", title=dict(text="stabilized share"), range=[-0.05, 1.05]),
        height=height,
        margin=dict(l=55, r=10, t=50, b=40),
        legend=dict(orientation="h", y=-0.3),
    )
    sides = [] if result is None else [(getattr(result, k), n, c) for k, n, c in SIDES if getattr(result, k)]
    if not sides:
        text = note or (
            result.error
            if result is not None and result.error
            else "set a bit budget (Data tab, folder Bit budget) to compute the budget study"
        )
        text = "<br>".join(textwrap.wrap(text, 34))  # a phone's plot is ~350 px wide
        layout["annotations"] = [dict(text=text, showarrow=False, x=0.5, y=0.5, xref="paper", yref="paper")]
        layout["title"] = dict(text="a link of limited bandwidth", font=dict(size=11))
        for key in ("xaxis", "xaxis2", "yaxis", "yaxis2"):
            layout[key]["visible"] = False
        return figure([], layout)
    data: list[dict[str, Any]] = []
    shapes: list[dict[str, Any]] = []
    first = sides[0][0].to_dict()
    for res, name, col in sides:
        d = res.to_dict()
        noise = d["config"].get("noise") or [0.0]
        label = name if name == "noise-free" else f"σ = {','.join(f'{v:g}' for v in noise)}"
        more, lines = _side(d, label, col)
        data += more
        shapes += lines
    c = first["config"]
    layout["shapes"] = shapes
    layout["title"] = dict(
        text=(
            f"budget {c['total_bits']:g} bits · runs of {c['steps']} steps · {c['realizations']} realizations · "
            f"{c['estimator'].upper()}<br>Model error err_G and share of loops that converge, against b; dotted: each knee"
        ),
        font=dict(size=11),
    )
    return figure(data, layout)


def _build(frame: FrameView) -> go.Figure:
    res = getattr(frame, "budget", None)
    note = "" if res is not None or not float(getattr(frame.values, "total_bits", 0.0)) else "computing the budget …"
    return bandwidth_figure(res, note=note)


#: Rebuilt with the curves: a tab's frames carry the budget once it is done (the renderer's rows key holds it).
VIEW = View("bandwidth", aspect=0.62, depends=CURVES, build=_build, tab="Bandwidth")
#: The same view in a nonlinear plant's group.
KOOPMAN_VIEW = View("koopman-bandwidth", aspect=0.62, depends=CURVES, build=_build, tab="Nonlinear")
