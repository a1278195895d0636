"""View: relative errors of A^ and B^ against the word length b (the letter's panels (a), (b))."""

from __future__ import annotations

import numpy as np
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from .palette import COLORS, color
from .traces import BITS_AXIS, Series, band, mark_bits, xy
from .view import CURVES, View

__all__ = ["error_figure", "VIEW"]


def _theory_and_reference(fig, rows, key: str, col: int, ref_slope: float) -> None:
    """Theorem 1's prediction (dashed) and a ``ref_slope``/bit line through the first mean (dotted)."""
    tx, ty = xy(rows, f"{key}_theory")
    if tx:
        fig.add_trace(go.Scatter(x=tx, y=ty, mode="lines", name="Theorem 1", legendgroup="th",
                                 showlegend=(col == 1), line=dict(color=COLORS["theory"], dash="dash")),
                      row=1, col=col)
    mx, my = xy(rows, key, "mean")
    if mx:
        b = np.array([mx[0], max(mx[-1], mx[0] + 1)])
        ry = my[0] * 10.0 ** (ref_slope * (b - mx[0]))
        fig.add_trace(go.Scatter(x=b.tolist(), y=ry.tolist(), mode="lines", name=f"{ref_slope:+.3f}/bit",
                                 legendgroup="ref", showlegend=(col == 1),
                                 line=dict(color=COLORS["ref"], dash="dot")), row=1, col=col)


def error_figure(series: Series, current_bits: int | None = None, ref_slope: float = -0.301,
                 height: int = 330) -> go.Figure:
    """Relative errors of A^ and B^ against b (two panels, log y).

    Each series draws mean +- std over realizations; the Theorem 1 prediction
    (taken from the first series) is dashed; a grey dotted line of slope
    ``ref_slope`` per bit (the letter's -0.301 = -log10 2) passes through the
    first series' mean at the smallest b; the current b is marked.
    """
    fig = make_subplots(rows=1, cols=2, subplot_titles=("‖A−Â‖/‖A‖", "‖B−B̂‖/‖B‖"), horizontal_spacing=0.12)
    for i, (label, rows) in enumerate(series.items()):
        for col, key in ((1, "err_A"), (2, "err_B")):
            band(fig, rows, key, color(label, i), label, row=1, col=col, showlegend=(col == 1))
            if i == 0:
                _theory_and_reference(fig, rows, key, col, ref_slope)
    fig.update_yaxes(type="log", exponentformat="power")
    fig.update_xaxes(**BITS_AXIS)
    mark_bits(fig, current_bits, row="all", col="all")
    fig.update_layout(height=height, margin=dict(l=50, r=10, t=30, b=40), legend=dict(orientation="h", y=-0.25),
                      template="plotly_white")
    return fig


VIEW = View("error", aspect=0.62, depends=CURVES,
            build=lambda frame: error_figure(frame.series(), current_bits=frame.bits, height=300))
