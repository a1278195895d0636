"""One closed-loop step at a time, for the loops where a bound is active: the box QPs of many models at once by
primal-dual active-set iterations, each model's own solver (DAQP, OSQP) where those do not settle."""

from __future__ import annotations

import numpy as np

from ..errors import FailureKind, MPCFailure
from .condensed_qp import box_qp_batch
from .loop_state import DIVERGED, LoopState

__all__ = ["solve_slow", "step", "step_small"]


def solve_slow(
    loops: LoopState, idx: np.ndarray, xs: np.ndarray, zs: np.ndarray, t: int
) -> tuple[np.ndarray, np.ndarray]:
    """``u_0`` of the models ``idx`` (states ``xs``) whose unconstrained optimum ``zs`` violates a bound.

    Box-only DAQP problems are first solved all at once by a few primal-dual
    active-set iterations (:func:`box_qp_batch`) from a guess: the previous
    step's active set shifted by one step (receding horizon), or at the first
    constrained step the bounds the unconstrained optimum violates. Where that
    does not settle -- and for state boxes or OSQP -- the model's own solver is
    called (DAQP warm-starts from its last active set). Failures are recorded.
    Returns ``(u (S, m), solved (S,))``.
    """
    m, ub = loops.m, loops.ub
    loops.out.qp_steps += idx.size
    if loops.solver_is_daqp:
        loops.condensed()
    u = np.empty((idx.size, m))
    todo = np.ones(idx.size, dtype=bool)
    if loops.guess:
        j, cq = loops.rows(idx), loops.qps()
        g = np.einsum("lij,lj->li", cq.Gx[j], xs) + cq.g0[j]
        if loops.preview is not None:
            g += loops.preview.g(j, t)
        prev = loops.prevU[idx]
        shifted = np.concatenate([prev[:, m:], prev[:, -m:]], axis=1)
        fresh = (loops.prev_t[idx] != t - 1)[:, None]  # no solution at the previous step: guess afresh
        base = np.where(fresh, zs[:, : ub.size], shifted)
        hi, lo = base >= ub * (1 - 1e-9), base <= -ub * (1 - 1e-9)
        U, ok = box_qp_batch(cq.H[j], g, ub, hi, lo)
        loops.prevU[idx[ok]] = U[ok]
        loops.prev_t[idx[ok]] = t
        u[ok] = U[ok, :m]
        todo = ~ok
    solved = np.ones(idx.size, dtype=bool)
    for a in np.flatnonzero(todo):
        i, c = int(idx[a]), loops.ctrl(idx[a])
        if loops.preview is not None:
            loops.preview.set_qp(c.daqp(), loops.pos[i], t)
        try:
            if c.solver == "daqp":
                U = c.solve_daqp(xs[a])
                loops.prevU[i], loops.prev_t[i], u[a] = U, t, U[:m]
            else:
                u[a], J = c.solve_qp(xs[a])
                if t == 0:
                    loops.out.J0[i] = J
        except MPCFailure as exc:
            loops.fail(i, exc.kind, f"step {t}: {exc}")
            solved[a] = False
    if t == 0 and loops.solver_is_daqp:  # the predicted optimal cost J*(x0) of the first problem
        for a in np.flatnonzero(solved):
            c = loops.ctrl(idx[a])
            if loops.preview is not None:
                loops.preview.set_qp(c.daqp(), loops.pos[idx[a]], 0)
            loops.out.J0[idx[a]] = c.qp_cost(xs[a], loops.prevU[idx[a]])
    # the active set meets the bounds up to rounding: clip that rounding
    return np.clip(u, -loops.w.u_max, loops.w.u_max), solved


def step_small(loops: LoopState, active: np.ndarray, t: int) -> tuple[np.ndarray, bool]:
    """:func:`step` for a few models, one at a time: the same law, the QP by the model's own solver."""
    m, out = loops.m, loops.out
    keep, all_fast = [], True
    for i in active:
        c, x = loops.ctrl(i), loops.x[i]
        y = loops.seen(x[None], t)[0]
        z = c.F @ y + c.f
        if loops.preview is not None:
            z = z + loops.preview.offsets(loops.pos[[i]], t, 1)[0, 0]
            loops.preview.set_qp(c.daqp(), loops.pos[i], t)
        fast = bool(np.all(np.abs(z) <= c.bound))
        try:
            if fast:
                u, J = z[:m], (loops.first_cost(i, y, z[: loops.nU]) if t == 0 else np.nan)
            else:
                out.qp_steps += 1
                u, J = c.solve_qp(y)
        except MPCFailure as exc:
            loops.fail(i, exc.kind, f"step {t}: {exc}")
            continue
        if t == 0:
            out.J0[i] = J
        xn = loops.moved(x[None], np.asarray(u)[None], t)[0]  # the true plant moves
        if not np.all(np.isfinite(xn)) or np.abs(xn).max() > DIVERGED:
            loops.fail(i, FailureKind.DIVERGED, f"closed loop diverged at step {t + 1}")
            continue
        out.states[i, t + 1], out.inputs[i, t] = xn, u
        loops.acc[i] += loops.stage_cost(x[None], np.asarray(u)[None], t)[0]
        loops.x[i] = xn
        keep.append(i)
        all_fast &= fast
    return np.array(keep, dtype=int), all_fast


def step(loops: LoopState, active: np.ndarray, t: int) -> tuple[np.ndarray, bool]:
    """One closed-loop step of every active model; the QP solver only where a bound is active.

    Returns the models still running and whether all of them took the fast path
    (then the caller goes back to :func:`~qsid_core.control.loop_fast.speculate`).
    """
    j = loops.rows(active)
    xi = loops.x[active]
    yi = loops.seen(xi, t)
    z1 = np.einsum("lrn,ln->lr", loops.F[j], yi) + loops.f[j]
    if loops.preview is not None:
        z1 += loops.preview.offsets(j, t, 1)[:, 0]
    fast_ok = np.all(np.abs(z1) <= loops.bound, axis=1)
    u = z1[:, : loops.m].copy()
    keep = np.ones(active.size, dtype=bool)
    slow = np.flatnonzero(~fast_ok)
    if slow.size:
        u[slow], ok = solve_slow(loops, active[slow], yi[slow], z1[slow], t)
        keep[slow] = ok
    if t == 0:
        for a in np.flatnonzero(fast_ok):
            loops.out.J0[active[a]] = loops.first_cost(int(active[a]), yi[a], z1[a, : loops.nU])
    xn = loops.moved(xi, u, t)  # the true plant moves: x+ = A x + B u (+ w)
    bad = ~np.all(np.isfinite(xn), axis=1) | (np.abs(xn).max(axis=1) > DIVERGED)
    for a in np.flatnonzero(bad & keep):
        loops.fail(int(active[a]), FailureKind.DIVERGED, f"closed loop diverged at step {t + 1}")
        keep[a] = False
    sel = active[keep]
    loops.out.states[sel, t + 1] = xn[keep]
    loops.out.inputs[sel, t] = u[keep]
    loops.acc[sel] += (
        loops.stage_cost(xi[keep], u[keep], t)
        if loops.preview is None
        else loops.stage_cost(xi[keep][:, None], u[keep][:, None], t)[:, 0]
    )
    loops.x[sel] = xn[keep]
    return sel, bool(fast_ok[keep].all())
