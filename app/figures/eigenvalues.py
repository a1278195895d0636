"""View: eigenvalues of the identified A^ at the current b, the true ones and the unit circle.

For a nonlinear plant (:data:`LIFTED_VIEW`, a frame whose result holds a lifting): the eigenvalues of the lifted
A_z at the current b (every realization, per estimator) against those of the unquantized EDMD of the same data."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import plotly.graph_objects as go

from .palette import COLORS, color
from .raw import arr, figure
from .view import CURRENT, FrameView, View

__all__ = ["eigen_figure", "lifted_eigenvalues", "LIFTED_VIEW", "VIEW"]


def eigen_figure(
    eigs: Mapping[str, np.ndarray] | np.ndarray, true_eigs: np.ndarray, height: int = 320, title: str = ""
) -> go.Figure:
    """Eigenvalues over realizations (``eigs``: complex array (R, n), or label -> such arrays).

    NaN eigenvalues (failed identifications) are not drawn by plotly.
    """
    if not isinstance(eigs, Mapping):
        eigs = {"Â": eigs}
    th = np.linspace(0, 2 * np.pi, 181)
    data = [
        dict(
            type="scatter",
            x=arr(np.cos(th)),
            y=arr(np.sin(th)),
            mode="lines",
            name="unit circle",
            line=dict(color=COLORS["unit_circle"], width=1),
            hoverinfo="skip",
        )
    ]
    # the true eigenvalues first, as open rings: the estimates are drawn over them and stay visible
    te = np.asarray(true_eigs).reshape(-1)
    data.append(
        dict(
            type="scatter",
            x=arr(te.real),
            y=arr(te.imag),
            mode="markers",
            name="eig A (true)",
            marker=dict(color=COLORS["true"], symbol="circle-open", size=14, line=dict(width=1.5)),
        )
    )
    for i, (label, ev) in enumerate(eigs.items()):
        ev = np.asarray(ev).reshape(-1)
        data.append(
            dict(
                type="scatter",
                x=arr(ev.real),
                y=arr(ev.imag),
                mode="markers",
                name=f"eig {label}",
                marker=dict(color=color(label, i), size=6, opacity=0.6),
            )
        )
    return figure(
        data,
        dict(
            height=height,
            margin=dict(l=50, r=10, t=30 if title else 10, b=40),
            legend=dict(orientation="h", y=-0.25),
            xaxis=dict(title=dict(text="Re"), zeroline=True),
            yaxis=dict(title=dict(text="Im"), scaleanchor="x", scaleratio=1, zeroline=True),
            **({"title": dict(text=title)} if title else {}),
        ),
    )


def _build(frame: FrameView) -> go.Figure:
    eigs = {lab: frame.idents[lab].eigenvalues for lab in frame.labels}
    return eigen_figure(eigs, frame.system.eigenvalues, height=300, title=f"eigenvalues of Â at b = {frame.bits}")


VIEW = View("eigen", aspect=0.75, depends=CURRENT, build=_build)


def lifted_eigenvalues(models: Any) -> np.ndarray:
    """Eigenvalues of every model's A_z (NaN rows for failed identifications), shape (R, L)."""
    rows = [np.linalg.eigvals(m.A) if m is not None else None for m in models]
    L = next((r.size for r in rows if r is not None), 0)
    return np.array([r if r is not None else np.full(L, np.nan) for r in rows], dtype=complex).reshape(-1, L)


def _lifted_build(frame: Any) -> go.Figure:
    eigs = {lab: lifted_eigenvalues(frame.models[lab].models) for lab in frame.labels}
    fig = eigen_figure(
        eigs, np.linalg.eigvals(frame.reference.A), height=300, title=f"eigenvalues of A_z at b = {frame.bits}"
    )
    fig.data[1].name = "unquantized EDMD"
    return fig


def _lifted_key(frame: Any) -> Any:
    return (frame.bits, tuple(id(frame.models[lab]) for lab in frame.labels))


#: The view of a nonlinear frame (its result holds a lifting): A_z's eigenvalues against the unquantized EDMD's.
LIFTED_VIEW = View("koopman-eigen", aspect=0.75, depends=CURRENT, build=_lifted_build, tab="Nonlinear", key=_lifted_key)
