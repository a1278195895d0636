"""View (live 3-D): the closed loops at the current b as arrays for the dashboard's viser scene.

:func:`scene_view` is pure (frame -> :class:`SceneView`); :class:`app.dashboard.scene.PhasePortrait`
pushes a SceneView into a tab's scene nodes.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .palette import vertex_rgb
from .view import FrameView

__all__ = [
    "CLIP",
    "SPHERE_CAP",
    "TIME",
    "SceneView",
    "scene_view",
    "axes_options",
    "axes_indices",
    "circles",
    "interleave",
    "scene_points",
    "to_segments",
]

#: Display coordinates are clipped to +-CLIP box units (diverging loops would swamp the view).
CLIP = 6.0
#: A bound circle is drawn to scale up to this radius (box units); larger: an off-scale label instead.
SPHERE_CAP = 1.6
#: For n <= 2 the free axis is time: step t is drawn at TIME * t / steps box units.
TIME = 1.2
#: Time markers: about this many dots along the true-model loop.
TIME_MARKS = 10
#: time markers closer than this (box units) to the previous one are not drawn (dots 0.035 wide; ~20 px apart)
MARK_GAP = 0.15

#: The state drawn on each display axis (x, y, z); None marks an axis without a state.
Dims = tuple[int, int | None, int | None]


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
    time_marks : float32 array (K, 3)
        Dots on the true-model loop every ``mark_every`` steps.
    start : array (3,)
        x0 in display units.
    scale : float
        State units per box unit.
    delta, delta_realized : float or None
        The letter's delta(eps) and the a-posteriori median (state units).
    bound_circles, realized_circles : float32 array (K, 2, 3)
        Outline circles of the two bounds around x_ref = 0 (empty if off scale or hidden).
    bound_text : str
        Both bounds in words (with "off scale" where a circle would not fit).
    show_bound : bool
    sphere_radius : float
        The letter's bound in box units (uncapped; 0 if none).
    sphere_capped : bool
        It does not fit the view (:data:`SPHERE_CAP`): no circle, an off-scale label.
    axis_names : tuple of 3 str
        State names; "time" on the free axis of 1- and 2-state systems; "" for an unused axis.
    failed, clipped, polylines, realizations : int
        Failed loops (hidden), loops leaving the view, distinct loops drawn, loops computed.
    mark_every : int
    not_converged : int
        Drawn loops judged bounded or diverged on the true plant (they never settle).
    ref_segments : float32 array (T, 2, 3)
        The path of a time-varying reference (empty for a constant one); for a nonlinear plant, its free flow.
    caption : tuple of str
        The lines under the scene when they are not the linear loops' (a nonlinear plant's); () for those.
    """

    segments: np.ndarray
    colors: np.ndarray
    true_segments: np.ndarray
    time_marks: np.ndarray
    start: np.ndarray
    scale: float
    delta: float | None
    delta_realized: float | None
    bound_circles: np.ndarray
    realized_circles: np.ndarray
    bound_text: str
    show_bound: bool
    sphere_radius: float
    sphere_capped: bool
    axis_names: tuple[str, ...]
    failed: int
    clipped: int
    polylines: int
    realizations: int
    mark_every: int
    not_converged: int = 0
    ref_segments: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 3), dtype=np.float32))
    caption: tuple[str, ...] = ()


def axes_options(names: Iterable[str]) -> list[str]:
    """3-D view choices: every set of three states (the first is the default); fewer than 3 states -> one."""
    names = list(names)
    if len(names) <= 3:
        return [", ".join(names)]
    return [", ".join(c) for c in itertools.combinations(names, 3)]


def axes_indices(choice: str, names: Iterable[str]) -> Dims:
    """Indices of the states drawn on the x, y, z axes (None pads systems with fewer than 3 states)."""
    names = list(names)
    opts = axes_options(names)
    if choice not in opts:
        choice = opts[0]
    if len(names) <= 3:
        idx = list(range(len(names)))
    else:
        idx = list(
            next(c for c in itertools.combinations(range(len(names)), 3) if ", ".join(names[i] for i in c) == choice)
        )
    pad: list[int | None] = [*idx, None, None]
    return (idx[0], pad[1], pad[2])


def _time_axis(dims: Dims) -> int | None:
    """The display axis that shows time (the first unused one) for 1- and 2-state systems."""
    return dims.index(None) if None in dims else None


def scene_points(states: NDArray[np.float64], dims: Dims, scale: float) -> NDArray[np.float64]:
    """(R, T+1, n) states -> (R, T+1, 3) display points (time on the free axis of small systems)."""
    R, T1, _ = states.shape
    P = np.zeros((R, T1, 3))
    for j, d in enumerate(dims):
        if d is not None:
            P[:, :, j] = states[:, :, d] / scale
    ta = _time_axis(dims)
    if ta is not None:
        P[:, :, ta] = TIME * np.arange(T1) / max(T1 - 1, 1)
    return P


def interleave(parts: list[NDArray[Any]], per_loop: int) -> NDArray[Any]:
    """Concatenate per-estimator segment arrays, alternating loop by loop (``per_loop`` segments each) when
    they are equally long, so that neither estimator's loops are all drawn over the other's."""
    p0 = parts[0]
    if len(parts) > 1 and per_loop > 0 and all(p.shape == p0.shape for p in parts) and p0.shape[0] % per_loop == 0:
        loops = [p.reshape((-1, per_loop) + p0.shape[1:]) for p in parts]
        return np.stack(loops, axis=1).reshape((-1,) + p0.shape[1:])
    return np.concatenate(parts)


def _reference_path(frame: FrameView, dims: Dims, scale: float, start: NDArray[np.float64]) -> NDArray[np.float32]:
    """Display segments of a time-varying reference over the drawn loop (empty when it is constant)."""
    mpc = frame.ex.config.mpc if frame.ex is not None else None
    if mpc is None or mpc.reference is None:
        return np.zeros((0, 2, 3), dtype=np.float32)
    path = mpc.resolve(frame.system).reference
    if path is None:
        return np.zeros((0, 2, 3), dtype=np.float32)
    ref = path[: mpc.steps + 1]
    seg, _, _ = to_segments(ref[None], dims, scale, start)
    return np.clip(seg, -CLIP, CLIP).astype(np.float32)


def to_segments(
    states: NDArray[np.float64], dims: Dims, scale: float, start: NDArray[np.float64]
) -> tuple[NDArray[np.float64], int, int]:
    """(R, T+1, n) trajectories -> (R*T, 2, 3) display segments, #failed, #clipped."""
    R = states.shape[0]
    P = scene_points(states, dims, scale)
    bad = ~np.all(np.isfinite(P.reshape(R, -1)), axis=1)
    P[bad] = start
    clipped = int(np.sum(np.any(np.abs(P.reshape(R, -1)) > CLIP, axis=1)))
    np.clip(P, -CLIP, CLIP, out=P)
    seg = np.stack([P[:, :-1, :], P[:, 1:, :]], axis=2).reshape(-1, 2, 3)
    return seg, int(bad.sum()), clipped


def _display_scale(true_states: NDArray[np.float64], x0: NDArray[np.float64], sel: list[int]) -> float:
    """Largest |state| of the true-model loop on the drawn axes (else of x0, else 1)."""
    ref = true_states[:, sel]
    ref = ref[np.all(np.isfinite(ref), axis=1)]
    scale = float(np.abs(ref).max()) if ref.size else 0.0
    if not np.isfinite(scale) or scale <= 0:
        scale = float(np.abs(x0[sel]).max())
        scale = scale if np.isfinite(scale) and scale > 0 else 1.0
    return scale


def circles(radius: float, dims: Dims, k: int = 48) -> NDArray[np.float32]:
    """Outline of a ball of ``radius`` (box units) around the origin: one circle per pair of state axes
    ((K, 2, 3) segments); small systems: in the state plane (or a segment for n = 1) at the last time."""
    state_axes = [j for j, d in enumerate(dims) if d is not None]
    ta = _time_axis(dims)
    th = np.linspace(0.0, 2.0 * np.pi, k + 1)
    segs = []
    if len(state_axes) == 1:
        p = np.zeros((2, 3))
        p[:, state_axes[0]] = (-radius, radius)
        if ta is not None:
            p[:, ta] = TIME
        return p[None].astype(np.float32)
    for a, b in itertools.combinations(state_axes, 2):
        p = np.zeros((k + 1, 3))
        p[:, a], p[:, b] = radius * np.cos(th), radius * np.sin(th)
        if ta is not None:
            p[:, ta] = TIME
        segs.append(np.stack([p[:-1], p[1:]], axis=1))
    return np.concatenate(segs).astype(np.float32)


def _bounds(frame: FrameView, dims: Dims, scale: float) -> dict[str, Any]:
    """The two bounds: circles drawn to scale when they fit, else words only."""
    first = frame.rows[frame.labels[0]].get(frame.bits, {})
    d0 = frame.theory.delta
    d = float(d0) if d0 is not None and np.isfinite(d0) and d0 > 0 else None
    rb0 = (first.get("ultimate_bound_realized") or {}).get("median")
    rb = float(rb0) if rb0 is not None and np.isfinite(rb0) and rb0 > 0 else None
    show = bool(getattr(frame.values, "show_bound", True))
    empty = np.zeros((0, 2, 3), dtype=np.float32)
    out: dict[str, Any] = {}
    words: list[str] = []
    for key, val, name in (("bound_circles", d, "letter's δ(ε)"), ("realized_circles", rb, "a-posteriori δ")):
        r = val / scale if val is not None else 0.0
        fits = 0 < r <= SPHERE_CAP
        out[key] = circles(r, dims) if (fits and show) else empty
        if val is None:
            words.append(f"{name}: no bound at this b")
        else:
            words.append(f"{name} = {val:.3g}" + ("" if fits else f" (off scale: {r:.3g} box units)"))
    radius = d / scale if d is not None else 0.0
    out.update(
        delta=d,
        delta_realized=rb,
        show_bound=show,
        sphere_radius=radius,
        sphere_capped=radius > SPHERE_CAP,
        bound_text="\n".join(words + ["as t → ∞, around x_ref = 0"]),
    )  # one per line: fits the canvas
    return out


def _spread(marks: NDArray[np.float64], gap: float = MARK_GAP) -> NDArray[np.float64]:
    """Drop time markers closer than ``gap`` (box units) to the last one kept: once the loop has converged
    its markers all sit on one point, where they piled into one black blob over the origin."""
    if marks.shape[0] == 0:
        return marks
    keep = [0]
    for k in range(1, marks.shape[0]):
        if np.linalg.norm(marks[k] - marks[keep[-1]]) >= gap:
            keep.append(k)
    return marks[keep]


def scene_view(frame: FrameView, axes: str | None = None) -> SceneView:
    """What the 3-D phase portrait draws for ``frame``: closed loops at the current b, the
    true-model loop with time markers, the start point, and the two bounds as outlines.

    The display scale is the largest |state| of the true-model loop on the drawn axes
    (so that loop fits the unit box); the bounds use the same scale. ``axes`` (e.g.
    ``"u, q, theta"``) defaults to the frame's panel choice.
    """
    names = frame.system.state_names
    dims = axes_indices(axes if axes is not None else frame.values.axes, names)
    assert frame.true_loop is not None  # a frame the views draw has the true-model loop
    ts = frame.true_loop.states[0]
    x0 = np.asarray(frame.x0, dtype=float)  # the engine's start state (also if loops failed)
    scale = _display_scale(ts, x0, [d for d in dims if d is not None])
    start = scene_points(x0[None, None, :], dims, scale)[0, 0]
    segs: list[NDArray[np.float64]] = []
    cols: list[NDArray[np.uint8]] = []
    failed, clipped, poly, total, stuck = 0, 0, 0, 0, 0
    for i, lab in enumerate(frame.labels):
        st = frame.loops[lab].states
        s, f, c = to_segments(st, dims, scale, start)
        segs.append(s)
        cols.append(np.broadcast_to(np.array(vertex_rgb(lab, i), dtype=np.uint8), s.shape))
        failed += f
        clipped += c
        oc = frame.loops[lab].outcome_counts()
        stuck += oc.get("bounded", 0) + oc.get("diverged", 0)
        total += st.shape[0]
        ident = frame.idents.get(lab)
        poly += min(st.shape[0], ident.effective_realizations if ident is not None else st.shape[0])
    tseg, _, _ = to_segments(ts[None], dims, scale, start)
    every = max(1, (ts.shape[0] - 1) // TIME_MARKS)
    marks = np.clip(scene_points(ts[None, ::every], dims, scale)[0], -CLIP, CLIP)
    marks = marks[np.all(np.isfinite(marks), axis=1)]
    ta = _time_axis(dims)
    if ta is not None:  # time axis: the markers sit at their own times
        marks[:, ta] = TIME * np.arange(0, ts.shape[0], every)[: len(marks)] / max(ts.shape[0] - 1, 1)
    marks = _spread(marks)
    labels = [names[d] if d is not None else "" for d in dims]
    if ta is not None:
        labels[ta] = "time"
    seg_all, col_all = interleave(list(segs), ts.shape[0] - 1), interleave(list(cols), ts.shape[0] - 1)
    return SceneView(
        segments=seg_all.astype(np.float32),
        colors=np.ascontiguousarray(col_all),
        true_segments=tseg.astype(np.float32),
        time_marks=marks.astype(np.float32),
        start=start,
        scale=scale,
        axis_names=tuple(labels),
        failed=failed,
        clipped=clipped,
        polylines=poly,
        realizations=total,
        mark_every=every,
        not_converged=stuck,
        ref_segments=_reference_path(frame, dims, scale, start),
        **_bounds(frame, dims, scale),
    )
