"""View: eigenvalues of the identified A^ at the current b, the true ones and the unit circle."""

from __future__ import annotations

from typing import Mapping

import numpy as np
import plotly.graph_objects as go

from .palette import COLORS, color
from .view import CURRENT, View

__all__ = ["eigen_figure", "VIEW"]


def eigen_figure(eigs: Mapping[str, np.ndarray] | np.ndarray, true_eigs: np.ndarray, height: int = 320,
                 title: str = "") -> go.Figure:
    """Eigenvalues over realizations (``eigs``: complex array (R, n), or label -> such arrays).

    NaN eigenvalues (failed identifications) are not drawn by plotly.
    """
    if not isinstance(eigs, Mapping):
        eigs = {"Â": eigs}
    th = np.linspace(0, 2 * np.pi, 181)
    fig = go.Figure(go.Scatter(x=np.cos(th), y=np.sin(th), mode="lines", name="unit circle",
                               line=dict(color=COLORS["unit_circle"], width=1), hoverinfo="skip"))
    for i, (label, ev) in enumerate(eigs.items()):
        ev = np.asarray(ev).reshape(-1)
        fig.add_trace(go.Scatter(x=ev.real, y=ev.imag, mode="markers", name=f"eig {label}",
                                 marker=dict(color=color(label, i), size=6, opacity=0.5)))
    te = np.asarray(true_eigs).reshape(-1)
    fig.add_trace(go.Scatter(x=te.real, y=te.imag, mode="markers", name="eig A (true)",
                             marker=dict(color=COLORS["true"], symbol="x", size=11)))
    fig.update_xaxes(title_text="Re", zeroline=True)
    fig.update_yaxes(title_text="Im", scaleanchor="x", scaleratio=1, zeroline=True)
    fig.update_layout(height=height, margin=dict(l=50, r=10, t=30 if title else 10, b=40), template="plotly_white",
                      title=title or None, legend=dict(orientation="h", y=-0.25))
    return fig


def _build(frame) -> go.Figure:
    eigs = {lab: frame.idents[lab].eigenvalues for lab in frame.labels}
    return eigen_figure(eigs, frame.system.eigenvalues, height=300, title=f"eigenvalues of Â at b = {frame.bits}")


VIEW = View("eigen", aspect=0.75, depends=CURRENT, build=_build)
