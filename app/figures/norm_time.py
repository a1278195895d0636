"""View: ``||x_t||`` against t at the current b (log y) with both ultimate bounds as horizontal lines.

The bounds hold only as t -> inf (and assume x_ref = 0): the lines show where the
loops must end up, not a limit at every t. Converged norms (below ``1e-12 ||x0||``,
the engine's :mod:`qsid_core.timeseries` floor) are drawn at the floor.
"""

from __future__ import annotations

import numpy as np
import plotly.graph_objects as go

from qsid_core.timeseries import time_series

from .hypotheses import CAPTION
from .palette import COLORS, color
from .view import CURRENT, View

__all__ = ["norm_time_figure", "VIEW"]


def _hline(fig, y, name: str, c: str, dash: str) -> None:
    if y is not None and np.isfinite(y) and y > 0:
        fig.add_hline(y=y, line=dict(color=c, dash=dash, width=1.5), annotation_text=f"{name} {y:.3g}",
                      annotation_position="top right", annotation_font_size=9)


def norm_time_figure(loops: dict, x0, true_loop=None, letter_delta: float | None = None,
                     realized: dict | None = None, bits: int | None = None, height: int = 300) -> go.Figure:
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
    """
    fig = go.Figure()
    floor = None
    for i, (label, lp) in enumerate(loops.items()):
        ts = time_series(lp, x0)
        floor = ts.norm_floor
        d = ts.norms_display[ts.ok]
        if d.size == 0:
            continue
        t = ts.t.tolist()
        c = color(label, i)
        fig.add_trace(go.Scatter(x=t + t[::-1], y=np.nanmax(d, 0).tolist() + np.nanmin(d, 0)[::-1].tolist(),
                                 fill="toself", fillcolor=c, opacity=0.15, line=dict(width=0), hoverinfo="skip",
                                 showlegend=False, legendgroup=label))
        fig.add_trace(go.Scatter(x=t, y=np.nanmedian(d, 0).tolist(), mode="lines", legendgroup=label,
                                 name=f"{label} ‖x_t‖ (median; band: min..max)", line=dict(color=c)))
    if true_loop is not None:
        ts = time_series(true_loop, x0)
        if ts.ok[0]:
            fig.add_trace(go.Scatter(x=ts.t.tolist(), y=ts.norms_display[0].tolist(), mode="lines",
                                     name="true model", line=dict(color=COLORS["true"], width=1.5)))
    _hline(fig, letter_delta, "letter's δ(ε)", COLORS["theory"], "dash")
    for label, rb in (realized or {}).items():
        _hline(fig, (rb or {}).get("median"), f"a-posteriori δ {label}", COLORS["realized"], "dot")
    if floor is not None:
        fig.add_hline(y=floor, line=dict(color=COLORS["ref"], dash="dot", width=1),
                      annotation_text="converged (1e-12‖x0‖)", annotation_position="bottom right",
                      annotation_font_size=9)
    fig.update_yaxes(type="log", title_text="‖x_t‖", exponentformat="power")
    fig.update_xaxes(title_text="closed-loop step t")
    title = CAPTION + (f" · b = {bits}" if bits is not None else "")
    fig.update_layout(height=height, margin=dict(l=50, r=10, t=30, b=40), template="plotly_white",
                      legend=dict(orientation="h", y=-0.3), title=dict(text=title, font=dict(size=11), x=0.01))
    return fig


def _build(frame) -> go.Figure:
    first = frame.rows[frame.labels[0]][frame.bits]
    realized = {lab: frame.rows[lab][frame.bits].get("ultimate_bound_realized") for lab in frame.labels}
    return norm_time_figure({lab: frame.loops[lab] for lab in frame.labels}, frame.x0, frame.true_loop,
                            first.get("ultimate_bound"), realized, bits=frame.bits, height=300)


VIEW = View("norm_time", aspect=0.75, depends=CURRENT, build=_build,
            key=lambda frame: (frame.bits, tuple(id(frame.loops[lab]) for lab in frame.labels)))
