"""View (live 3-D): the closed loops at the current b as arrays for the dashboard's viser scene.

:func:`scene_view` is pure (frame -> :class:`SceneView`); :class:`app.dashboard.scene.PhasePortrait`
pushes a SceneView into a tab's scene nodes.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from .palette import vertex_rgb

__all__ = ["CLIP", "SPHERE_CAP", "SceneView", "scene_view", "axes_options", "axes_indices"]

#: Display coordinates are clipped to +-CLIP box units (diverging loops would swamp the view).
CLIP = 6.0
#: The bound sphere is drawn at most this many box units wide (larger bounds are drawn capped, as wireframe).
SPHERE_CAP = 1.6


@dataclass
class SceneView:
    """Arrays for the viser scene, in display units (state / ``scale``).

    Attributes
    ----------
    segments : float32 array (N, 2, 3)
        One polyline per realization (and per estimator) as line segments; failed
        realizations are collapsed onto the start point; clipped to +-:data:`CLIP`.
    colors : uint8 array (N, 2, 3)
        RGB of every segment end: the estimator's palette colour as linear light
        (:func:`app.figures.palette.vertex_rgb`), so the screen shows the palette colour.
    true_segments : float32 array (T, 2, 3)
        The true-model closed loop.
    start : array (3,)
        x0 in display units.
    scale : float
        State units per box unit.
    sphere_radius, sphere_capped, delta
        Bound sphere radius (box units, at most :data:`SPHERE_CAP`), whether capped, delta(eps) (state units).
    axis_names : tuple of 3 str
    failed, clipped, polylines : int
        Failed realizations (hidden), realizations leaving the view, realizations drawn.
    """

    segments: np.ndarray
    colors: np.ndarray
    true_segments: np.ndarray
    start: np.ndarray
    scale: float
    sphere_radius: float
    sphere_capped: bool
    delta: float | None
    axis_names: tuple
    failed: int
    clipped: int
    polylines: int


def axes_options(names) -> list:
    """3-D view choices: every set of three states (the first is the default); fewer than 3 states -> one."""
    names = list(names)
    if len(names) <= 3:
        return [", ".join(names)]
    return [", ".join(c) for c in itertools.combinations(names, 3)]


def axes_indices(choice: str, names) -> tuple:
    """Indices of the states drawn on the x, y, z axes (None pads systems with fewer than 3 states)."""
    names = list(names)
    opts = axes_options(names)
    if choice not in opts:
        choice = opts[0]
    if len(names) <= 3:
        idx = list(range(len(names)))
    else:
        idx = list(next(c for c in itertools.combinations(range(len(names)), 3)
                        if ", ".join(names[i] for i in c) == choice))
    return tuple(idx + [None] * (3 - len(idx)))


def _to_segments(states: np.ndarray, dims: tuple, scale: float, start: np.ndarray) -> tuple:
    """(R, T+1, n) trajectories -> (R*T, 2, 3) display segments, #failed, #clipped."""
    R, T1, _ = states.shape
    P = np.zeros((R, T1, 3))
    for j, d in enumerate(dims):
        if d is not None:
            P[:, :, j] = states[:, :, d] / scale
    bad = ~np.all(np.isfinite(P.reshape(R, -1)), axis=1)
    P[bad] = start
    clipped = int(np.sum(np.any(np.abs(P.reshape(R, -1)) > CLIP, axis=1)))
    np.clip(P, -CLIP, CLIP, out=P)
    seg = np.stack([P[:, :-1, :], P[:, 1:, :]], axis=2).reshape(-1, 2, 3)
    return seg, int(bad.sum()), clipped


def _display_scale(true_states: np.ndarray, x0: np.ndarray, sel: list) -> float:
    """Largest |state| of the true-model loop on the drawn axes (else of x0, else 1)."""
    ref = true_states[:, sel]
    ref = ref[np.all(np.isfinite(ref), axis=1)]
    scale = float(np.abs(ref).max()) if ref.size else 0.0
    if not np.isfinite(scale) or scale <= 0:
        scale = float(np.abs(x0[sel]).max())
        scale = scale if np.isfinite(scale) and scale > 0 else 1.0
    return scale


def scene_view(frame, axes: str | None = None) -> SceneView:
    """What the 3-D phase portrait draws for ``frame``: closed loops at the current b, the
    true-model loop, the start point, and the bound sphere, all divided by one display scale.

    The display scale is the largest |state| of the true-model loop on the drawn axes
    (so that loop fits the unit box); the sphere of radius delta(eps) uses the same scale.
    ``axes`` (e.g. ``"u, q, theta"``) defaults to the frame's panel choice.
    """
    names = frame.system.state_names
    dims = axes_indices(axes if axes is not None else frame.values.axes, names)
    ts = frame.true_loop.states[0]
    x0 = np.asarray(frame.x0, dtype=float)  # the engine's start state (also if loops failed)
    scale = _display_scale(ts, x0, [d for d in dims if d is not None])
    start = np.array([x0[d] / scale if d is not None else 0.0 for d in dims])
    segs, cols, failed, clipped, poly = [], [], 0, 0, 0
    for i, lab in enumerate(frame.labels):
        st = frame.loops[lab].states
        s, f, c = _to_segments(st, dims, scale, start)
        segs.append(s)
        cols.append(np.broadcast_to(np.array(vertex_rgb(lab, i), dtype=np.uint8), s.shape))
        failed += f
        clipped += c
        poly += st.shape[0]
    tseg, _, _ = _to_segments(ts[None], dims, scale, start)
    delta = frame.theory.delta
    ok = delta is not None and np.isfinite(delta) and delta > 0
    radius = float(delta) / scale if ok else 0.0
    return SceneView(
        segments=np.concatenate(segs).astype(np.float32), colors=np.ascontiguousarray(np.concatenate(cols)),
        true_segments=tseg.astype(np.float32), start=start, scale=scale,
        sphere_radius=min(radius, SPHERE_CAP), sphere_capped=radius > SPHERE_CAP,
        delta=float(delta) if ok else None,
        axis_names=tuple(names[d] if d is not None else "-" for d in dims), failed=failed, clipped=clipped,
        polylines=poly,
    )
