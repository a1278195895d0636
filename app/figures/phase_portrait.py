"""View (offline HTML): 3-D phase portrait of closed loops, as a plotly figure (``qsid reproduce``).

The live dashboard draws the same picture with viser nodes (:mod:`app.figures.phase_scene`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import plotly.graph_objects as go

from .palette import COLORS, color

__all__ = ["phase_portrait_figure"]


def phase_portrait_figure(
    states: np.ndarray,
    true_states: np.ndarray | None = None,
    dims=(0, 1, 2),
    names: Sequence[str] | None = None,
    title: str = "",
    height: int = 520,
    label: str = "LS",
) -> go.Figure:
    """One line per realization (``states``: (R, T+1, n)) plus the true-model trajectory ((T+1, n)).

    ``dims`` picks the three states drawn (for 4-state systems); ``label`` (the
    estimator) picks the colour of the realizations; the true model is black.
    Realizations with no finite point on the drawn states are skipped.
    """
    states = np.asarray(states, dtype=float)
    names = list(names) if names is not None else [f"x{i + 1}" for i in range(states.shape[-1])]
    i, j, k = dims
    xs, ys, zs = [], [], []
    for tr in states:
        ok = np.all(np.isfinite(tr[:, [i, j, k]]), axis=1)
        if not ok.any():
            continue
        xs += tr[ok, i].tolist() + [None]
        ys += tr[ok, j].tolist() + [None]
        zs += tr[ok, k].tolist() + [None]
    fig = go.Figure(
        go.Scatter3d(
            x=xs,
            y=ys,
            z=zs,
            mode="lines",
            name=f"{states.shape[0]} realizations",
            line=dict(color=color(label), width=2),
            opacity=0.6,
        )
    )
    if true_states is not None:
        ts = np.asarray(true_states, dtype=float)
        fig.add_trace(
            go.Scatter3d(
                x=ts[:, i],
                y=ts[:, j],
                z=ts[:, k],
                mode="lines",
                name="true model",
                line=dict(color=COLORS["true"], width=5),
            )
        )
        fig.add_trace(
            go.Scatter3d(
                x=[ts[0, i]],
                y=[ts[0, j]],
                z=[ts[0, k]],
                mode="markers",
                name="x0",
                marker=dict(color=COLORS["true"], size=5),
            )
        )
    fig.update_layout(
        title=title or None,
        height=height,
        margin=dict(l=0, r=0, t=40 if title else 10, b=0),
        scene=dict(xaxis_title=names[i], yaxis_title=names[j], zaxis_title=names[k]),
        legend=dict(orientation="h", y=0.02),
    )
    return fig
