"""View: ``||x_t||`` against t at the current b (log y) with both ultimate bounds as horizontal lines.

The bounds hold only as t -> inf (and assume x_ref = 0): the lines show where the
loops must end up, not a limit at every t. Converged norms (below ``1e-12 ||x0||``,
the engine's :mod:`qsid_core.control.timeseries` floor) are drawn at the floor.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import plotly.graph_objects as go

from qsid_core import TimeSeries, time_series

from .axes import top_log_range
from .hypotheses import CAPTION
from .palette import COLORS, color
from .raw import arr, figure, hline
from .traces import hline_note
from .view import CURRENT, FrameView, View

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

    from qsid_core import ClosedLoops

__all__ = ["norm_time_figure", "VIEW"]


def _hline(
    shapes: list[dict[str, Any]],
    notes: list[dict[str, Any]],
    y: float | None,
    name: str,
    c: str,
    dash: str,
    width: float = 1.5,
    where: str = "top",
) -> None:
    """A labelled horizontal line at ``y`` (skipped unless finite and > 0: the y axis is log)."""
    if y is None or not np.isfinite(y) or y <= 0:
        return
    shapes.append(hline(float(y), "y", c, dash, width))
    if name:  # labels staggered right, left, middle: lines close together do not print them on each other
        notes.append(hline_note(y, name, where=where, size=9, x=(1.0, 0.0, 0.5)[len(notes) % 3], color=c))


def _realized_lines(
    shapes: list[dict[str, Any]], notes: list[dict[str, Any]], realized: dict[str, dict[str, float] | None]
) -> None:
    """The a-posteriori bound of each estimator (its median) as a dotted line; medians within 25 % of each other
    draw lines on top of each other, so one label names them all."""
    found = [(label, (rb or {}).get("median")) for label, rb in realized.items()]
    medians = [(label, float(y)) for label, y in found if y is not None and np.isfinite(y) and y > 0]
    together = len(medians) > 1 and max(y for _, y in medians) <= 1.25 * min(y for _, y in medians)
    joint = "a-posteriori δ " + ", ".join(f"{label} {_g(y)}" for label, y in medians)
    for k, (label, y) in enumerate(medians):
        name = (joint if k == 0 else "") if together else f"a-posteriori δ {label} {_g(y)}"
        _hline(shapes, notes, y, name, COLORS["realized"], "dot")


def norm_time_figure(
    loops: dict[str, ClosedLoops],
    x0: ArrayLike,
    true_loop: ClosedLoops | None = None,
    letter_delta: float | None = None,
    realized: dict[str, dict[str, float] | None] | None = None,
    bits: int | None = None,
    height: int = 300,
) -> go.Figure:
    """Median and min..max band of ``||x_t||`` per estimator, the true-model loop, both bounds.

    Parameters
    ----------
    loops : dict label -> ClosedLoops
        Closed loops at one word length (``states`` (R, T+1, n)).
    x0 : array_like (n,)
        Start state (sets the convergence floor).
    true_loop : ClosedLoops, optional
    letter_delta : float, optional
        The letter's delta(eps) (state units).
    realized : dict label -> {"median", "max"}, optional
        The a-posteriori bound per estimator.

    Built from plain dicts (:mod:`.raw`): this view is redrawn on every b change.
    """
    data: list[dict[str, Any]] = []
    shapes: list[dict[str, Any]] = []
    notes: list[dict[str, Any]] = []
    floor = None
    for i, (label, lp) in enumerate(loops.items()):
        ts = time_series(lp, x0)
        floor = ts.norm_floor
        data += _band(ts, label, color(label, i))
    if true_loop is not None:
        ts = time_series(true_loop, x0)
        if ts.ok[0]:
            data.append(
                dict(
                    type="scatter",
                    x=ts.t.tolist(),
                    y=arr(ts.norms_display[0]),
                    mode="lines",
                    name="true model",
                    line=dict(color=COLORS["true"], width=1.5),
                )
            )
    _hline(shapes, notes, letter_delta, f"letter's δ(ε) {_g(letter_delta)}", COLORS["theory"], "dash")
    _realized_lines(shapes, notes, realized or {})
    ys = [v for tr in data for v in tr["y"] if v is not None and np.isfinite(v) and v > 0]
    converged = floor is not None and bool(ys) and min(ys) <= floor * (1 + 1e-9)
    if converged:  # the floor line only when some loop reached it (else it stretched the axis for nothing)
        _hline(shapes, notes, floor, "converged (1e-12‖x0‖)", COLORS["ref"], "dot", 1.0, where="bottom")
    title = CAPTION + (f" · b = {bits}" if bits is not None else "")
    yaxis: dict[str, Any] = dict(type="log", title=dict(text="‖x_t‖"), exponentformat="power")
    # top-anchored: the start of the loops and both bounds always show (axes.top_log_range)
    rng = top_log_range(ys + [s["y0"] for s in shapes])
    if rng is not None:
        yaxis.update(range=rng, autorange=False)
        if ys and np.log10(min(ys)) < rng[0]:
            yaxis["title"]["text"] = (
                "‖x_t‖ (" + ("converged tails" if converged else "some values") + " below the axis)"
            )
    return figure(
        data,
        dict(
            height=height,
            margin=dict(l=50, r=10, t=30, b=40),
            legend=dict(orientation="h", y=-0.3),
            title=dict(text=title, font=dict(size=11), x=0.01),
            shapes=shapes,
            annotations=notes,
            yaxis=yaxis,
            xaxis=dict(title=dict(text="closed-loop step t")),
        ),
    )


def _band(ts: TimeSeries, label: str, c: str) -> list[dict[str, Any]]:
    """The min..max band and the median of ``||x_t||`` over the loops that ran (none when no loop ran)."""
    d = ts.norms_display[ts.ok]
    if d.size == 0:
        return []
    t = ts.t.tolist()
    band = dict(  # the polygon: along the max forward, back along the min (x and y both 2 (T+1) long)
        type="scatter",
        x=t + t[::-1],
        y=arr(np.concatenate([np.nanmax(d, 0), np.nanmin(d, 0)[::-1]])),
        fill="toself",
        fillcolor=c,
        opacity=0.15,
        line=dict(width=0),
        hoverinfo="skip",
        showlegend=False,
        legendgroup=label,
    )
    median = dict(
        type="scatter",
        x=t,
        y=arr(np.nanmedian(d, 0)),
        mode="lines",
        legendgroup=label,
        name=f"{label} ‖x_t‖ (median; band: min..max)",
        line=dict(color=c),
    )
    return [band, median]


def _g(y: float | None) -> str:
    return f"{y:.3g}" if y is not None and np.isfinite(y) else ""


def _build(frame: FrameView) -> go.Figure:
    first = frame.rows[frame.labels[0]][frame.bits]
    realized = {lab: frame.rows[lab][frame.bits].get("ultimate_bound_realized") for lab in frame.labels}
    return norm_time_figure(
        {lab: frame.loops[lab] for lab in frame.labels},
        frame.x0,
        frame.true_loop,
        first.get("ultimate_bound"),
        realized,
        bits=frame.bits,
        height=300,
    )


VIEW = View(
    "norm_time",
    aspect=0.75,
    depends=CURRENT,
    build=_build,
    key=lambda frame: (frame.bits, tuple(id(frame.loops[lab]) for lab in frame.labels)),
)
