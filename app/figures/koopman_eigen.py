"""View (nonlinear plants): eigenvalues of the lifted A_z at the current b (every realization, per estimator)
against those of the unquantized EDMD of the same data, and the unit circle."""

from __future__ import annotations

from typing import Any

import numpy as np
import plotly.graph_objects as go

from .eigenvalues import eigen_figure
from .view import CURRENT, View

__all__ = ["VIEW", "lifted_eigenvalues"]


def lifted_eigenvalues(models: Any) -> np.ndarray:
    """Eigenvalues of every model's A_z (NaN rows for failed identifications), shape (R, L)."""
    rows = [np.linalg.eigvals(m.A) if m is not None else None for m in models]
    L = next((r.size for r in rows if r is not None), 0)
    return np.array([r if r is not None else np.full(L, np.nan) for r in rows], dtype=complex).reshape(-1, L)


def _build(frame: Any) -> go.Figure:
    eigs = {lab: lifted_eigenvalues(frame.models[lab].models) for lab in frame.labels}
    fig = eigen_figure(
        eigs, np.linalg.eigvals(frame.reference.A), height=300, title=f"eigenvalues of A_z at b = {frame.bits}"
    )
    fig.data[1].name = "unquantized EDMD"
    return fig


def _key(frame: Any) -> Any:
    return (frame.bits, tuple(id(frame.models[lab]) for lab in frame.labels))


VIEW = View("koopman-eigen", aspect=0.75, depends=CURRENT, build=_build, tab="Nonlinear", key=_key)
