"""View: realised closed-loop MPC cost on the true system against b (the letter's panel (c))."""

from __future__ import annotations

import numpy as np
import plotly.graph_objects as go

from .palette import COLORS, color
from .traces import BITS_AXIS, Series, band, mark_bits
from .view import CURVES, View

__all__ = ["cost_figure", "VIEW"]


def cost_figure(series: Series, true_cost: float | None = None, current_bits: int | None = None,
                height: int = 300) -> go.Figure:
    """Mean +- std of the closed-loop cost per estimator against b, and the true-model cost (dashed)."""
    fig = go.Figure()
    for i, (label, rows) in enumerate(series.items()):
        band(fig, rows, "mpc_cost", color(label, i), f"{label} model")
    if true_cost is not None and np.isfinite(true_cost):
        fig.add_hline(y=true_cost, line=dict(color=COLORS["true"], dash="dash"),
                      annotation_text=f"true model {true_cost:.4g}", annotation_position="top right")
    mark_bits(fig, current_bits)
    fig.update_yaxes(type="log", title_text="closed-loop cost")
    fig.update_xaxes(**BITS_AXIS)
    fig.update_layout(height=height, margin=dict(l=50, r=10, t=20, b=40), template="plotly_white",
                      legend=dict(orientation="h", y=-0.3))
    return fig


VIEW = View("cost", aspect=0.6, depends=CURVES,
            build=lambda frame: cost_figure(frame.series(), true_cost=frame.true_cost, current_bits=frame.bits,
                                            height=260))
