"""View (offline HTML): 3-D phase portrait of closed loops, as a plotly figure (``qsid reproduce``).

The live dashboard draws the same picture with viser nodes (:mod:`app.figures.phase_scene`).
Systems with fewer than three states put time on the missing axis: a 2-state system
draws (x1, x2, step) in 3-D, a 1-state system x1 against the step in 2-D.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import plotly.graph_objects as go
from numpy.typing import NDArray

from .palette import COLORS, color

__all__ = ["phase_portrait_figure"]

#: Axis title of the time axis that stands in for a missing state.
TIME_TITLE = "step k (time)"


def _with_time(
    states: NDArray[np.float64],
    true_states: NDArray[np.float64] | None,
    names: list[str],
    dims: tuple[int | None, ...],
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None, list[str], tuple[int | None, ...]]:
    """Append the step k as an extra 'state' and draw it on the first missing axis."""
    R, T1, n = states.shape
    k = np.broadcast_to(np.arange(T1, dtype=float)[None, :, None], (R, T1, 1))
    states = np.concatenate([states, k], axis=2)
    if true_states is not None:
        ts = np.asarray(true_states, dtype=float)
        true_states = np.concatenate([ts, np.arange(ts.shape[0], dtype=float)[:, None]], axis=1)
    pos = dims.index(None)
    dims = dims[:pos] + (n,) + dims[pos + 1 :]
    if None not in dims:
        return states, true_states, [*names, TIME_TITLE], dims
    # one state: a 2-D plot, time on x
    return states, true_states, [*names, TIME_TITLE], (dims[0], None, None) if pos != 0 else (n, None, None)


def _time_figure(
    states: NDArray[np.float64],
    true_states: NDArray[np.float64] | None,
    names: Sequence[str],
    d: int,
    title: str,
    height: int,
    label: str,
) -> go.Figure:
    """A 1-state system: every realization's x1 against the step k (2-D), the true model in black."""
    xs: list[int | None] = []
    ys: list[float | None] = []
    for tr in states:
        ok = np.isfinite(tr[:, d])
        if ok.any():
            xs += np.flatnonzero(ok).tolist() + [None]
            ys += tr[ok, d].tolist() + [None]
    fig = go.Figure(
        go.Scatter(
            x=xs,
            y=ys,
            mode="lines",
            name=f"{states.shape[0]} realizations",
            line=dict(color=color(label), width=1.5),
            opacity=0.6,
        )
    )
    if true_states is not None:
        ts = np.asarray(true_states, dtype=float)
        fig.add_trace(go.Scatter(y=ts[:, d], mode="lines", name="true model", line=dict(color=COLORS["true"], width=3)))
        fig.add_trace(
            go.Scatter(x=[0], y=[ts[0, d]], mode="markers", name="x0", marker=dict(color=COLORS["true"], size=8))
        )
    fig.update_layout(
        title=title or None,
        height=height,
        template="plotly_white",
        margin=dict(l=60, r=10, t=40 if title else 10, b=40),
        xaxis_title=TIME_TITLE,
        yaxis_title=names[d],
        legend=dict(orientation="h", y=-0.2),
    )
    return fig


def phase_portrait_figure(
    states: np.ndarray,
    true_states: np.ndarray | None = None,
    dims: Sequence[int | None] = (0, 1, 2),
    names: Sequence[str] | None = None,
    title: str = "",
    height: int = 520,
    label: str = "LS",
) -> go.Figure:
    """One line per realization (``states``: (R, T+1, n)) plus the true-model trajectory ((T+1, n)).

    ``dims`` picks the three states drawn (for 4-state systems); ``None`` entries
    (systems with fewer states) draw the step k instead: ``(0, 1, None)`` is a 3-D
    plot of x1, x2 and time, ``(0, None, None)`` a 2-D plot of x1 against time.
    ``label`` (the estimator) picks the colour of the realizations; the true model is black.
    Realizations with no finite point on the drawn states are skipped.
    """
    states = np.asarray(states, dtype=float)
    names = list(names) if names is not None else [f"x{i + 1}" for i in range(states.shape[-1])]
    dims = tuple(dims) + (None,) * (3 - len(dims))
    if None in dims:
        states, true_states, names, dims = _with_time(states, true_states, names, dims)
    if dims[1] is None:
        assert dims[0] is not None  # the drawn state (or the step k) is on the first axis
        return _time_figure(states, true_states, names, dims[0], title, height, label)
    i, j, k = dims
    assert i is not None and j is not None and k is not None  # the step k fills a missing axis
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
