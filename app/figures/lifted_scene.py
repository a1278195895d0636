"""View (live 3-D, offered when the result holds a lifting: a nonlinear plant): the plant's own flow and the Koopman MPC loops at the current b.

Axes: the first two states (x1, x2 of the presets) and time (0 .. the loops' length). Thin green lines: the
plant's free flow (u = 0) from a grid of initial states (the Van der Pol limit cycle, the pendulum's swings);
coloured: the Koopman MPC loops of every realization's model at the current b on the true plant (LS blue,
BCLS red); thick black: the loop of the unquantized EDMD's model. :func:`lifted_scene` is pure.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from .palette import vertex_rgb
from .phase_scene import CLIP, SceneView, interleave, scene_points, to_segments

__all__ = ["lifted_scene", "scene_arrays"]


def scene_arrays(frame: Any) -> dict[str, Any]:
    """The state arrays the portrait draws: ``flow`` (k, T+1, n), ``loops`` (label -> (R, T+1, n)), ``reference``
    ((T+1, n) or None), the drawn state indices ``dims`` and the display ``scale``."""
    flow = np.asarray(frame.flow, dtype=float)
    loops = {lab: frame.loops[lab].states for lab in frame.labels if frame.loops.get(lab) is not None}
    ref = frame.reference_loop.states[0] if frame.reference_loop is not None else None
    n = flow.shape[-1]
    dims = (0, 1 if n > 1 else None, None)
    sel = [d for d in dims if d is not None]
    parts = [flow[..., sel].reshape(-1)] + ([ref[:, sel].reshape(-1)] if ref is not None else [])
    vals = np.abs(np.concatenate(parts))
    vals = vals[np.isfinite(vals)]
    scale = float(vals.max()) if vals.size and vals.max() > 0 else 1.0
    return dict(flow=flow, loops=loops, reference=ref, dims=dims, scale=scale)


def _nan_tail(states: NDArray[np.float64]) -> NDArray[np.float64]:
    """A run that ended (NaN) holds its last finite state: its polyline stops there, not at the start point."""
    out = states.copy()
    for r in range(out.shape[0]):
        ok = np.all(np.isfinite(out[r]), axis=1)
        if not ok.all() and ok.any():
            last = int(np.flatnonzero(ok)[-1])
            out[r, last + 1 :] = out[r, last]
    return out


def lifted_scene(frame: Any) -> SceneView:
    """What the 3-D portrait draws for a nonlinear frame (see the module docstring)."""
    a = scene_arrays(frame)
    dims, scale = a["dims"], a["scale"]
    x0 = np.asarray(frame.x0, dtype=float)
    start = scene_points(x0[None, None, :], dims, scale)[0, 0]
    segs, cols = [], []
    failed = clipped = total = stuck = 0
    for i, (lab, st) in enumerate(a["loops"].items()):
        s, f, c = to_segments(_nan_tail(st), dims, scale, start)
        segs.append(s)
        cols.append(np.broadcast_to(np.array(vertex_rgb(lab, i), dtype=np.uint8), s.shape))
        failed, clipped, total = failed + f, clipped + c, total + st.shape[0]
        oc = frame.loops[lab].counts()
        stuck += oc["bounded"] + oc["diverged"]
    empty = np.zeros((1, 2, 3), dtype=np.float32)
    per_loop = next(iter(a["loops"].values())).shape[1] - 1 if a["loops"] else 1
    seg_all = interleave(segs, per_loop) if segs else empty
    col_all = interleave(cols, per_loop) if cols else np.zeros((1, 2, 3), dtype=np.uint8)
    ref = a["reference"]
    tseg = to_segments(_nan_tail(ref[None]), dims, scale, start)[0] if ref is not None else empty
    flow = to_segments(_nan_tail(a["flow"]), dims, scale, start)[0]
    names = frame.system.state_names
    labels = (names[0], names[1] if len(names) > 1 else "time", "time" if len(names) > 1 else "")
    conv = {lab: frame.loops[lab].counts()["converged"] for lab in a["loops"]}
    return SceneView(
        segments=np.clip(seg_all, -CLIP, CLIP).astype(np.float32),
        colors=np.ascontiguousarray(col_all),
        true_segments=np.clip(tseg, -CLIP, CLIP).astype(np.float32),
        time_marks=np.zeros((0, 3), dtype=np.float32),
        start=start,
        scale=scale,
        delta=None,
        delta_realized=None,
        bound_circles=np.zeros((0, 2, 3), dtype=np.float32),
        realized_circles=np.zeros((0, 2, 3), dtype=np.float32),
        bound_text="",
        show_bound=False,
        sphere_radius=0.0,
        sphere_capped=False,
        axis_names=labels,
        failed=failed,
        clipped=clipped,
        polylines=total,
        realizations=total,
        mark_every=1,
        not_converged=stuck,
        ref_segments=np.clip(flow, -CLIP, CLIP).astype(np.float32),
        caption=(
            f"axes: {labels[0]}, {labels[1]}, {labels[2]}",
            "green: the plant's own flow (u = 0)",
            f"Koopman MPC at b = {frame.bits}: "
            + ", ".join(f"{lab} {conv[lab]}/{frame.loops[lab].states.shape[0]} converged" for lab in conv),
            "black: the unquantized EDMD's loop",
            f"1 box unit = {scale:.3g}",
        ),
    )
