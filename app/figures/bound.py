"""View: the two ultimate bounds against b, and the measured final state norm.

* the letter's delta(eps) (green, dashed): from Theorem 1's predicted (T -> inf) model errors;
* the a-posteriori delta (purple): from each realization's own model error and its own P,
  median (line) and max (band) over realizations -- the honest companion for finite data;
* ``||x_T||`` mean and max per estimator at the end of the drawn closed loops.

Both bounds hold only as t -> inf and assume the reference x_ref = 0 (caption).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import plotly.graph_objects as go

from qsid_core.control import CONVERGED_REL_FLOOR

from .axes import top_log_range
from .hypotheses import CAPTION
from .palette import COLORS, color
from .raw import figure, hline
from .traces import BITS_AXIS, Rows, Series, hline_note, mark_bits, xy
from .view import CURVES, FrameView, View

__all__ = ["bound_figure", "VIEW", "CAPTION"]


def _realized(rows: Rows, label: str, c: str, dash: str = "solid") -> list[dict[str, Any]]:
    """Trace dicts: median line and median..max band of the a-posteriori bound of one estimator."""
    mx, my = xy(rows, "ultimate_bound_realized", "median")
    if not mx:
        return []
    out: list[dict[str, Any]] = []
    top = dict(zip(*xy(rows, "ultimate_bound_realized", "max")))
    bx = [b for b in mx if b in top]
    if bx:
        lo = dict(zip(mx, my))
        out.append(
            dict(
                type="scatter",
                x=bx + bx[::-1],
                y=[top[b] for b in bx] + [lo[b] for b in bx[::-1]],
                fill="toself",
                fillcolor=c,
                opacity=0.15,
                line=dict(width=0),
                hoverinfo="skip",
                showlegend=False,
                legendgroup=f"re{label}",
            )
        )
    out.append(
        dict(
            type="scatter",
            x=mx,
            y=my,
            mode="lines+markers",
            legendgroup=f"re{label}",
            name=f"a-posteriori δ, {label} (median; band: max)",
            line=dict(color=c, width=1.5, dash=dash),
            marker=dict(symbol="diamond", size=5),
        )
    )
    return out


def _floored(ys: list[float], floor: float | None) -> tuple[list[float], bool]:
    if floor is None:
        return ys, False
    return [max(y, floor) for y in ys], any(y < floor for y in ys)


def _no_bound(rows: Rows) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Shapes shading the b where the letter's delta >= rho (its proof then gives no bound), and the legend's key
    to them (a trace without data)."""
    bad = sorted(r["bits"] for r in rows if r.get("bound_self_consistent") is False)
    runs: list[list[int]] = []
    for b in bad:
        if runs and b == runs[-1][1] + 1:
            runs[-1][1] = b
        else:
            runs.append([b, b])
    shapes = [
        dict(
            type="rect",
            xref="x",
            yref="paper",
            x0=lo - 0.5,
            x1=hi + 0.5,
            y0=0,
            y1=1,
            layer="below",
            fillcolor=COLORS["ref"],
            opacity=0.12,
            line=dict(width=0),
        )
        for lo, hi in runs
    ]
    # named in the legend, not written over the traces: a grey square for the shaded word lengths
    key = dict(
        type="scatter",
        x=[None],
        y=[None],
        mode="markers",
        marker=dict(symbol="square", size=12, color=COLORS["ref"], opacity=0.3),
        name="shaded: δ ≥ ρ, no bound",
        hoverinfo="skip",
    )
    return shapes, [key] if runs else []


def bound_figure(
    series: Series,
    current_bits: int | None = None,
    height: int = 300,
    floor: float | None = None,
    steps: int | None = None,
    x0_norm: float | None = None,
    theory_per_series: bool = False,
) -> go.Figure:
    """Letter's delta(eps) (dashed), a-posteriori delta per series (median, max band), ``|x_T|`` mean and max.

    ``floor`` (state units, e.g. ``1e-12 ||x0||``): final norms below it are converged and drawn at it
    (floating-point noise such as 1e-48 is no distance to the origin). The b where the letter's
    delta is not below its rho are shaded (the proof assumes the state stays within rho: there it
    gives no bound); ``x0_norm`` is drawn as a line (a bound above it says less than the start).
    The letter's delta is the first series' unless ``theory_per_series``: then every series whose
    delta differs gets its own dashed line in its colour (equal ones are drawn once).
    """
    data: list[dict[str, Any]] = []
    conv = False
    drawn: list[tuple[list[int], list[float]]] = []
    several = theory_per_series and len({repr(xy(rows, "ultimate_bound")) for rows in series.values()}) > 1
    for i, (label, rows) in enumerate(series.items()):
        c = color(label, i)
        bx, by = xy(rows, "ultimate_bound")
        if i == 0 or (theory_per_series and (bx, by) not in drawn):
            data.append(
                dict(
                    type="scatter",
                    x=bx,
                    y=by,
                    mode="lines+markers",
                    name="letter's δ(ε) (Theorem 1 errors)" + (f" · {label}" if several else ""),
                    legendgroup="th" if i == 0 else f"th {i}",
                    line=dict(color=COLORS["theory"] if i == 0 else c, dash="dash"),
                )
            )
            drawn.append((bx, by))
        # every a-posteriori δ in the bound colour (not the estimator's: BCLS δ and BCLS ‖x_T‖ looked alike)
        data += _realized(rows, label, COLORS["realized"], "solid" if i == 0 else "dot")
        norms, floored = _final_norms(rows, label, c, floor)
        data += norms
        conv = conv or floored
    shapes = mark_bits(current_bits)
    first_rows = next(iter(series.values()), [])
    shade, shade_key = _no_bound(first_rows)
    shapes += shade
    notes = [_caption(steps)]
    if x0_norm is not None and x0_norm > 0:
        shapes.append(hline(float(x0_norm), "y", COLORS["true"], "dashdot", 1.0))
        notes.append(hline_note(x0_norm, f"‖x0‖ = {x0_norm:.3g}", x=0.0, size=9))
        data.append(
            dict(type="scatter", x=[None], y=[float(x0_norm)], mode="lines", showlegend=False, hoverinfo="skip")
        )
    yaxis: dict[str, Any] = dict(type="log", title=dict(text="norm"), exponentformat="power")
    # the bounds always show; final norms off the axis sit on its edge, marked (_off_axis)
    bounds = [v for tr in data if "δ" in tr.get("name", "") for v in tr["y"]]
    rng = top_log_range([v for tr in data for v in tr["y"]], keep=bounds)
    if rng is not None:
        yaxis.update(range=rng, autorange=False)
        data += _off_axis(data, rng)
    if conv and floor is not None and (rng is None or np.log10(floor) >= rng[0]):
        shapes.append(hline(float(floor), "y", COLORS["ref"], "dot", 1.0))
        notes.append(hline_note(floor, "converged (‖x_T‖ ≤ 1e-12‖x0‖)", where="bottom", size=9))
    data += shade_key
    return figure(
        data,
        dict(
            height=height,
            margin=dict(l=50, r=10, t=30, b=40),
            legend=dict(orientation="h", y=-0.3),
            shapes=shapes,
            annotations=notes,
            xaxis=dict(BITS_AXIS),
            yaxis=yaxis,
        ),
    )


def _final_norms(rows: Rows, label: str, c: str, floor: float | None) -> tuple[list[dict[str, Any]], bool]:
    """``(traces, floored)``: the mean (line) and max (triangles) of ``‖x_T‖`` per b, and whether a value
    was below ``floor`` (converged: drawn at the floor)."""
    mx, my = xy(rows, "final_state_norm", "mean")
    my, c1 = _floored(my, floor)
    xx, xy_ = xy(rows, "final_state_norm", "max")
    xy_, c2 = _floored(xy_, floor)
    mean = dict(type="scatter", x=mx, y=my, mode="lines+markers", name=f"{label} ‖x_T‖ mean", line=dict(color=c))
    top = dict(
        type="scatter",
        x=xx,
        y=xy_,
        mode="markers",
        name=f"{label} ‖x_T‖ max",
        marker=dict(color=c, symbol="triangle-up"),
    )
    return [mean, top], c1 or c2


def _caption(steps: int | None) -> dict[str, Any]:
    """The caption above the plot (what the letter's δ is; the loops' length when known)."""
    caption = CAPTION + ("" if steps is None else f" · ‖x_T‖: last state of the drawn loops, T = {steps} steps")
    return dict(
        text=caption,
        showarrow=False,
        x=0,
        y=1.02,
        xref="paper",
        yref="paper",
        xanchor="left",
        yanchor="bottom",
        font=dict(size=10, color=COLORS["ref"]),
    )


def _off_axis(data: list[dict[str, Any]], rng: list[float]) -> list[dict[str, Any]]:
    """The ``‖x_T‖`` points outside the axis range (decades), drawn on its edge as open triangles.

    Below: converged loops; above: diverged ones. The hover text gives the true value.
    """
    out: list[dict[str, Any]] = []
    for tr in data:
        if "‖x_T‖" not in tr.get("name", ""):
            continue
        c = (tr.get("line") or tr.get("marker") or {}).get("color")
        for where, test, y_edge, sym in (
            ("below", lambda y: y < 10.0 ** rng[0], rng[0] + 0.01, "triangle-down-open"),
            ("above", lambda y: y > 10.0 ** rng[1], rng[1] - 0.01, "triangle-up-open"),
        ):
            pts = [(b, y) for b, y in zip(tr["x"], tr["y"]) if y is not None and y > 0 and test(y)]
            if pts:  # one legend entry per edge ("‖x_T‖ below the axis"); the hover names the series
                first = not any(o["legendgroup"] == where for o in out)
                out.append(
                    dict(
                        type="scatter",
                        x=[b for b, _ in pts],
                        y=[10.0**y_edge] * len(pts),
                        mode="markers",
                        name=f"‖x_T‖ {where} the axis (hover: value)",
                        meta=tr["name"],
                        legendgroup=where,
                        showlegend=first,
                        text=[f"{y:.3g}" for _, y in pts],
                        hovertemplate=f"{tr['name']}, b = %{{x}}: %{{text}}<extra></extra>",
                        cliponaxis=False,
                        marker=dict(color=c, symbol=sym, size=9),
                    )
                )
    return out


def _build(frame: FrameView) -> go.Figure:
    r0 = float(np.linalg.norm(frame.x0))
    floor = CONVERGED_REL_FLOOR * (r0 if r0 > 0 else 1.0)
    return bound_figure(
        frame.series(), current_bits=frame.bits, height=300, floor=floor, steps=int(frame.values.mpc_steps), x0_norm=r0
    )


VIEW = View("bound", aspect=0.75, depends=CURVES, build=_build)
