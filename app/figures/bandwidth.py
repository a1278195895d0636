"""View: a link of limited bandwidth. At a fixed budget of bits, the model error and the stabilized share against
the word length b, noise-free and with the sensor noise side by side, the knee marked.

The numbers are :func:`qsid_core.studies.bandwidth`'s (two :class:`~qsid_core.studies.BudgetResult` s, their
``to_dict()``), which the tab's :class:`~qsid_core.studies.Study` computes after the curves when the "bit budget"
setting is not 0. Each side: ``err_G`` (mean ± std over the realizations, log) against b, the prediction dashed
(linear plants), the knee (the smallest b within 25 % of the least error) marked by a vertical dotted line and named
in the legend; under it the share of the loops that converge on the true plant against b (a nonlinear plant's:
converged, and dotted within the convergence radius). Noise-free only (no sensor noise set, or a nonlinear plant):
the error left, the share right. With sensor noise: two columns, noise-free (black) left and with the noise
(orange) right, each titled, the error panels on one scale so the two knees compare at a glance. Panels side by
side are stacked on a phone and in presenter mode (:func:`app.figures.room.lay_out`). With bits per sample set,
the title's last lines are the per-channel allocation: the proposed split, the uniform one, their measured errors
(:func:`allocation_lines`).
"""

from __future__ import annotations

import textwrap
from typing import Any

import numpy as np
import plotly.graph_objects as go

from .axes import finite_axes, log_ticks
from .raw import arr, figure
from .view import CURVES, FrameView, View

__all__ = ["bandwidth_figure", "allocation_lines", "VIEW", "KOOPMAN_VIEW", "SIDES", "AXES"]

#: The two sides: key of :class:`~qsid_core.studies.Bandwidth`, legend name, colour.
SIDES = (("noise_free", "noise-free", "#000000"), ("noisy", "with noise", "#ff7f0e"))
#: The prediction's colour of each side's (a lighter or darker shade: visible where it lies on the measurement).
PREDICTED = {"#000000": "#7f7f7f", "#ff7f0e": "#8c564b"}


def _mean(rows: list[dict[str, Any]], key: str) -> np.ndarray:
    return arr([np.nan if r.get(key) is None else r[key] for r in rows])


#: A low share panel's ticks: its ends only (three labels crowd it at presenter size).
ENDS = dict(tickvals=[0, 1], ticktext=["0", "1"])
#: The panels of one side: ``(err_G x, err_G y, share x, share y)`` axis ids, for the first and the second side.
AXES = (("x", "y", "x3", "y3"), ("x2", "y2", "x4", "y4"))


def _side(
    d: dict[str, Any], name: str, col: str, axes: tuple[str, str, str, str]
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Traces and knee line of one budget result ``d`` (``BudgetResult.to_dict()``) on the panels ``axes``."""
    xe, ye, xs, ys = axes
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
            xaxis=xe, yaxis=ye,
        ),
    ]  # fmt: skip
    if not d["nonlinear"] and any(r.get("predicted_err_G") is not None for r in rows):
        data.append(
            dict(
                type="scatter", x=b, y=_mean(rows, "predicted_err_G"), mode="lines",
                name=f"{name}: predicted (knee b = {d.get('b_knee_predicted')})", legendgroup=name,
                line=dict(color=PREDICTED[col], dash="dash", width=2), xaxis=xe, yaxis=ye,
            )
        )  # fmt: skip
    if d["config"]["mpc"]:
        data.append(
            dict(
                type="scatter", x=b, y=_mean(rows, "stabilized_fraction"), mode="lines+markers",
                name=f"{name}: stabilized", legendgroup=name, showlegend=False, line=dict(color=col),
                xaxis=xs, yaxis=ys,
            )
        )  # fmt: skip
        if d["nonlinear"]:
            n = arr([sum((r.get("closed_loop_outcomes") or {}).values()) or np.nan for r in rows])
            data.append(
                dict(
                    type="scatter", x=b, y=_mean(rows, "within_radius") / n, mode="lines",
                    name="within radius", legendgroup=name, line=dict(color=col, dash="dot"),
                    xaxis=xs, yaxis=ys,
                )
            )  # fmt: skip
    shapes = []
    if knee is not None:
        shapes.append(
            dict(
                type="line", xref=xe, yref=f"{ye} domain", x0=knee, x1=knee, y0=0, y1=1, name=f"knee {name}",
                line=dict(color=col, dash="dot", width=1.5),
            )
        )  # fmt: skip
    return data, shapes


def _axes_layout(two: bool) -> dict[str, Any]:
    """The panels' axes: one side, the error left and the share right; two sides, a column each (the error over
    the share), the second column's error on the first's scale."""
    bits = dict(text="word length b (bits)")
    err = dict(type="log", title=dict(text="err_G"), exponentformat="power")
    share = dict(title=dict(text="stabilized share"), range=[-0.05, 1.05])
    if not two:
        return dict(
            xaxis=dict(domain=[0, 0.5], title=bits, anchor="y", dtick=2),
            xaxis2=dict(domain=[0.66, 1], title=bits, anchor="y2", dtick=2),
            yaxis=dict(anchor="x", **err),
            yaxis2=dict(anchor="x2", **share),
        )
    left, right, top, low = [0, 0.42], [0.58, 1], [0.38, 1], [0, 0.17]
    # the low share panels are titled "share" (the figure's title says of what): "stabilized share", even
    # broken in two, stands taller than such a panel and runs into the error panel's lowest label above
    low_share = {**share, "title": dict(text="share"), **ENDS}
    return dict(
        xaxis=dict(domain=left, anchor="y", dtick=2),
        xaxis2=dict(domain=right, anchor="y2", dtick=2, matches="x"),
        xaxis3=dict(domain=left, anchor="y3", dtick=2, title=bits, matches="x"),
        xaxis4=dict(domain=right, anchor="y4", dtick=2, title=bits, matches="x"),
        yaxis=dict(domain=top, anchor="x", **err),
        yaxis2=dict(domain=top, anchor="x2", matches="y", **err),
        yaxis3=dict(domain=low, anchor="x3", **low_share),
        yaxis4=dict(domain=low, anchor="x4", **low_share),
    )


def _heads(sides: list[tuple[str, str]], layout: dict[str, Any]) -> list[dict[str, Any]]:
    """Each column's title, centred on its top edge (``sides``: (title, colour) per column)."""
    out = []
    for (text, col), xk in zip(sides, ("xaxis", "xaxis2")):
        x0, x1 = layout[xk]["domain"]
        out.append(
            dict(
                text=text, showarrow=False, xref="paper", yref="paper", x=(x0 + x1) / 2, y=1, xanchor="center",
                yanchor="bottom", font=dict(size=12, color=col),
            )
        )  # fmt: skip
    return out


def bandwidth_figure(result: Any, height: int = 360, note: str = "") -> go.Figure:
    """The bandwidth view of ``result`` (a :class:`~qsid_core.studies.Bandwidth`, or None: not computed)."""
    sides = [] if result is None else [(getattr(result, k), n, c) for k, n, c in SIDES if getattr(result, k)]
    layout: dict[str, Any] = dict(
        _axes_layout(len(sides) == 2),
        height=height,
        margin=dict(l=55, r=10, t=50, b=40),
        legend=dict(orientation="h", y=-0.3),
    )
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
    heads: list[tuple[str, str]] = []
    first = sides[0][0].to_dict()
    for i, (res, name, col) in enumerate(sides):
        d = res.to_dict()
        noise = d["config"].get("noise") or [0.0]
        label = name if name == "noise-free" else f"σ = {','.join(f'{v:g}' for v in noise)}"
        axes = AXES[i] if len(sides) == 2 else ("x", "y", "x2", "y2")
        more, lines = _side(d, label, col, axes)
        data += more
        shapes += lines
        known = " known to BCLS" if d["config"].get("noise_known") and d["config"]["estimator"] == "bcls" else ""
        heads.append((label if name == "noise-free" else f"sensor noise {label}{known}", col))
    layout["shapes"] = shapes
    split = allocation_lines(result)
    layout["title"] = _title(first["config"], split)
    top = (70 if len(sides) == 2 else 50) + 15 * len(split)
    layout["margin"] = dict(l=55, r=10, t=top, b=40)
    if len(sides) == 2:
        layout["annotations"] = _heads(heads, layout)
        return _one_scale(figure(data, layout))
    return figure(data, layout)


def allocation_lines(result: Any) -> list[str]:
    """The per-channel allocation's lines under the title: the two splits and their measured errors (none when
    no bits per sample were set; the reason when the allocation does not apply). Each starts with a capital, so
    a narrow layout does not join it to the line before as one sentence (:func:`app.figures.room.wrap_text`)."""
    if getattr(result, "allocation_note", ""):
        return [f"Per-channel split: {result.allocation_note}"]
    alloc = getattr(result, "allocation", None)
    if alloc is None:
        return []
    d = alloc.to_dict()
    c, pro, uni = d["config"], d["proposed"], d["uniform"]
    per = ", ".join(f"{n} {p}" for n, p in zip(d["channels"], pro["bits"]))
    even = len(set(uni["bits"])) == 1
    flat = f"{uni['bits'][0]} each" if even else ", ".join(str(v) for v in uni["bits"])
    return [
        f"Split of {c['bits_per_sample']} bits per sample ({d['trajectories']} runs): proposed {per}; uniform {flat}",
        f"Measured err_G: proposed {pro['err_G']['mean']:.3g}, uniform {uni['err_G']['mean']:.3g}: ratio "
        f"{d['ratio']['median']:.2f} (median), proposed better in {d['proposed_better']} of {c['realizations']}",
    ]


def _title(c: dict[str, Any], extra: list[str]) -> dict[str, Any]:
    head = (
        f"budget {c['total_bits']:g} bits · runs of {c['steps']} steps · {c['realizations']} realizations · "
        f"{c['estimator'].upper()}<br>Model error err_G and share of loops that converge, against b; dotted: each knee"
    )
    # from the figure's top edge down (plotly centres a title in the top margin: lines added would run into the
    # column titles standing on the panels' top edge)
    text = "<br>".join([head, *extra])
    return dict(text=text, font=dict(size=11), yref="container", y=1, yanchor="top", pad=dict(t=8))


def _one_scale(fig: go.Figure) -> go.Figure:
    """Both error panels on the range that holds both sides' error (each axis's own range by :func:`finite_axes`,
    then their union), with the ticks of that range: the two knees compare at a glance."""
    finite_axes(fig)
    a, b = fig.layout.yaxis, fig.layout.yaxis2
    if a.range is None or b.range is None:
        return fig
    rng = [min(a.range[0], b.range[0]), max(a.range[1], b.range[1])]
    ticks = log_ticks(rng) if rng[1] - rng[0] < 2.5 else dict(tickvals=None, ticktext=None)
    for ax in (a, b):
        ax.range = rng
        ax.tickvals, ax.ticktext = ticks["tickvals"], ticks["ticktext"]
        ax.tickmode = "array" if ticks["tickvals"] is not None else None
    return fig


def _build(frame: FrameView) -> go.Figure:
    res = getattr(frame, "budget", None)
    note = "" if res is not None or not float(getattr(frame.values, "total_bits", 0.0)) else "computing the budget …"
    return bandwidth_figure(res, note=note)


#: Rebuilt with the curves: a tab's frames carry the budget once it is done (the renderer's rows key holds it).
VIEW = View("bandwidth", aspect=0.7, depends=CURVES, build=_build, tab="Bandwidth")
#: The same view in a nonlinear plant's group.
KOOPMAN_VIEW = View("koopman-bandwidth", aspect=0.7, depends=CURVES, build=_build, tab="Nonlinear")
