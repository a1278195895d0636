"""View (offered when the result holds a lifting: a nonlinear plant): the multi-step prediction error of the lifted models on held-out runs of the true
plant, per word length, with the unquantized EDMD's own prediction error (the floor) as a dashed line."""

from __future__ import annotations

from typing import Any

import plotly.graph_objects as go

from .palette import COLORS, color
from .raw import figure, hline
from .traces import band, hline_note, mark_bits
from .view import CURVES, View

__all__ = ["VIEW", "prediction_figure"]


def prediction_figure(
    rows: dict[str, list[dict[str, Any]]], bits: int | None, floor: float | None, horizon: int, height: int = 300
) -> go.Figure:
    """log relative RMS error of the prediction over steps 1..``horizon`` vs b (mean ±std per estimator label)."""
    data: list[dict[str, Any]] = []
    for i, (lab, rs) in enumerate(rows.items()):
        data += band(rs, "prediction_error", color(lab, i), lab)
    shapes = mark_bits(bits)
    notes = []
    if floor is not None and floor > 0:
        shapes.append(hline(floor, "y", COLORS["true"]))
        notes.append(hline_note(floor, "unquantized EDMD", where="bottom", size=11, x=1.0))
    return figure(
        data,
        dict(
            height=height,
            margin=dict(l=60, r=10, t=10, b=40),
            legend=dict(orientation="h", y=-0.25),
            xaxis=dict(title=dict(text="word length b (bits)"), dtick=2),
            yaxis=dict(title=dict(text=f"prediction error, steps 1..{horizon}"), type="log", exponentformat="power"),
            shapes=shapes,
            annotations=notes,
        ),
    )


def _build(frame: Any) -> go.Figure:
    return prediction_figure(frame.series(), frame.bits, frame.reference_error, frame.horizon)


VIEW = View("koopman-prediction", aspect=0.55, depends=CURVES, build=_build, tab="Nonlinear")
