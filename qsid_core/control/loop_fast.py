"""The fast path of the batched closed loops: while the unconstrained LQ optimum is feasible, the MPC law is an
affine feedback, so every loop is simulated ahead and its predicted constraints checked in one batch."""

from __future__ import annotations

import numpy as np

from .loop_state import DIVERGED, LoopState

__all__ = ["speculate"]


def speculate(loops: LoopState, active: np.ndarray, t: int) -> tuple[np.ndarray, int]:
    """Run every active loop ahead on the fast path; commit the steps where it is the optimum.

    On the fast path the MPC law is the affine feedback ``u = F_u x + f_u`` (the
    first ``m`` rows of the prediction map), so the true closed loop is
    ``x+ = (A + B F_u) x + B f_u``. It is simulated for all remaining steps, and
    at each step every predicted constrained quantity ``z = F x + f`` is checked
    against its box: the unconstrained optimum is the constrained one iff
    ``|z| <= bound``. Models that never leave the fast path are finished; the
    others are committed up to the first step ``tau`` where any active model
    leaves it. Returns the still-active models and ``t + tau``.
    """
    n, m, out = loops.n, loops.m, loops.out
    j = loops.rows(active)
    Fu, fu = loops.F[j, :m], loops.f[j, :m]
    Mcl = loops.A[None] + np.einsum("ij,ljk->lik", loops.B, Fu)
    ccl = fu @ loops.B.T
    H = loops.steps - t
    xs = np.empty((active.size, H + 1, n))
    xs[:, 0] = loops.x[active]
    if loops.noise is None and loops.preview is None:
        for h in range(H):
            xs[:, h + 1] = np.einsum("lij,lj->li", Mcl, xs[:, h]) + ccl
        z = np.einsum("lrn,lhn->lhr", loops.F[j], xs[:, :H]) + loops.f[j][:, None, :]
    else:  # the law acts on what the controller measures and previews; the true plant may be disturbed
        z = np.zeros((active.size, H, loops.f.shape[1])) + loops.ref_offsets(j, t, H)
        for h in range(H):
            z[:, h] += np.einsum("lrn,ln->lr", loops.F[j], loops.seen(xs[:, h], t + h)) + loops.f[j]
            xs[:, h + 1] = loops.moved(xs[:, h], z[:, h, :m], t + h)
    ok = np.all(np.abs(z) <= loops.bound, axis=2)
    ok &= np.all(np.isfinite(xs[:, 1:]), axis=2) & (np.abs(xs[:, 1:]).max(axis=2) <= DIVERGED)
    first_bad = np.where(ok.all(axis=1), H, np.argmin(ok, axis=1))
    if t == 0:
        y0 = loops.seen(xs[:, 0], 0)
        for a, i in enumerate(active):
            if first_bad[a] > 0:
                out.J0[i] = loops.first_cost(i, y0[a], z[a, 0, : loops.nU])
    tau = int(first_bad.min())
    done = first_bad == H
    us = z[:, :, :m]
    for a, i in enumerate(active):
        k = H if done[a] else tau
        if k:
            out.states[i, t + 1 : t + k + 1] = xs[a, 1 : k + 1]
            out.inputs[i, t : t + k] = us[a, :k]
            loops.acc[i] += loops.stage_cost(xs[a, :k], us[a, :k], t).sum()
            loops.x[i] = xs[a, k]
    return active[~done], t + tau
