"""View: the ultimate bound delta(eps) against the measured final state norm, over b."""

from __future__ import annotations

import plotly.graph_objects as go

from .palette import COLORS, color
from .traces import BITS_AXIS, Series, mark_bits, xy
from .view import CURVES, View

__all__ = ["bound_figure", "VIEW"]


def bound_figure(series: Series, current_bits: int | None = None, height: int = 300) -> go.Figure:
    """delta(eps) (theory, from the first series, dashed) and ``|x_T|`` mean and max per series."""
    fig = go.Figure()
    for i, (label, rows) in enumerate(series.items()):
        c = color(label, i)
        if i == 0:
            bx, by = xy(rows, "ultimate_bound")
            fig.add_trace(go.Scatter(x=bx, y=by, mode="lines+markers", name="δ(ε) bound",
                                     line=dict(color=COLORS["theory"], dash="dash")))
        mx, my = xy(rows, "final_state_norm", "mean")
        fig.add_trace(go.Scatter(x=mx, y=my, mode="lines+markers", name=f"{label} ‖x_T‖ mean", line=dict(color=c)))
        xx, xy_ = xy(rows, "final_state_norm", "max")
        fig.add_trace(go.Scatter(x=xx, y=xy_, mode="markers", name=f"{label} ‖x_T‖ max",
                                 marker=dict(color=c, symbol="triangle-up")))
    mark_bits(fig, current_bits)
    fig.update_yaxes(type="log", title_text="norm", exponentformat="power")
    fig.update_xaxes(**BITS_AXIS)
    fig.update_layout(height=height, margin=dict(l=50, r=10, t=20, b=40), template="plotly_white",
                      legend=dict(orientation="h", y=-0.3))
    return fig


def _build(frame) -> go.Figure:
    fig = bound_figure(frame.series(), current_bits=frame.bits, height=260)
    fig.add_annotation(text="δ(ε) assumes regulation to x_ref = 0", showarrow=False, x=1, y=1.02, xref="paper",
                       yref="paper", xanchor="right", yanchor="bottom", font=dict(size=10, color=COLORS["ref"]))
    return fig


VIEW = View("bound", aspect=0.6, depends=CURVES, build=_build)
