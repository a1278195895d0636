"""Closed loops: the MPC built on each identified model, run on the true system.

:func:`run_closed_loops` runs many models at once. While the unconstrained LQ
optimum is feasible the MPC law is an affine feedback, so the loop is simulated
ahead and every predicted constraint checked in one batch; only the steps where
a bound is active solve a QP: the condensed box QPs of all such models at once by
primal-dual active-set iterations (compiled, :func:`qsid_core.quantization.kernels.box_qp_pdas`),
and DAQP (:mod:`qsid_core.control.condensed_qp`) where those do not settle or a state box
is set. Where the input box is the only constraint, the state is measured exactly
and the reference is constant, the whole loop runs compiled instead, the same law
step by step (:mod:`qsid_core.control.loop_kernel`). ``solver="osqp"`` runs the previous
engine's OSQP path instead. Failures are recorded per model, never raised.
"""

from __future__ import annotations

import numpy as np

from ..errors import FailureKind, MPCFailure
from .condensed_qp import box_qp_batch, condense
from .controllers import build_controllers
from .loop_kernel import eligible, run_compiled
from .loop_noise import LoopNoise, loop_noise
from .loop_results import ClosedLoops
from .mpc import MPCConfig
from .mpc_weights import MPCWeights
from .tracking import Preview
from .verdicts import judge

__all__ = ["run_closed_loops"]

#: a state beyond this norm (max-abs) counts as diverged
DIVERGED = 1e12
#: at most this many models are stepped model by model (numpy's per-call overhead dominates tiny batches)
SMALL = 4


class _Loops:
    """State of the batched closed loops (arrays indexed by realisation ``i``)."""

    def __init__(
        self,
        ctrls: list,
        w: MPCWeights,
        A: np.ndarray,
        B: np.ndarray,
        steps: int,
        out: ClosedLoops,
        x_start: np.ndarray | None = None,
        cq=None,
        noise: LoopNoise | None = None,
    ):
        self.ctrls, self.w, self.A, self.B, self.steps, self.out = ctrls, w, A, B, steps, out
        self.noise = noise  # disturbance and measurement draws (None: exact state feedback, no disturbance)
        self.preview: Preview | None = None  # a time-varying reference (None: the constant x_ref)
        self.offset_free = False  # the input cost (u - u_ref)'R(u - u_ref) instead of the letter's u'R u
        self.n, self.m = B.shape
        live = np.flatnonzero([c is not None for c in ctrls])
        self.live = live
        # fast-path prediction maps of the live models: z = F x + f stacks u_0..u_{N-1} [, x_1..x_N]
        self.F = np.stack([ctrls[i].F for i in live])  # (L, rows, n)
        self.f = np.stack([ctrls[i].f for i in live])  # (L, rows)
        self.bound = ctrls[live[0]].bound  # (rows,)
        self.pos = np.full(len(ctrls), -1)  # realisation -> row of the live arrays
        self.pos[live] = np.arange(live.size)
        self.acc = np.zeros(len(ctrls))  # realised cost so far
        # current true state per realisation (x0, or where an earlier run stopped)
        self.x = np.tile(w.x0, (len(ctrls), 1)) if x_start is None else np.array(x_start, dtype=float)
        out.states[live, 0] = self.x[live]
        self.first_costs = x_start is None  # record J*(x0) of the first problem (not for a continued run)
        self.cq = cq  # condensed QPs of the live models (built at the first constrained step)
        # box-only problems solved by DAQP: guess the active set in one batch, DAQP only where the guess fails
        self.solver_is_daqp = ctrls[live[0]].solver == "daqp"
        self.guess = self.solver_is_daqp and self.bound.size == ctrls[live[0]].N * self.m  # no state rows
        self.nU = ctrls[live[0]].N * self.m  # condensed variables u_0..u_{N-1}
        self.prevU = np.full((len(ctrls), self.nU), np.nan)  # last optimal input sequence per model
        self.prev_t = np.full(len(ctrls), -2)  # the step it was computed at
        self.ub = np.tile(w.u_max, self.nU // self.m)  # box of U = [u_0; ...; u_{N-1}]

    def seen(self, x: np.ndarray, t: int) -> np.ndarray:
        """What the controller measures of true states ``x`` (shape (L, n)) at step ``t``."""
        return x if self.noise is None else self.noise.measure(x, t)

    def moved(self, x: np.ndarray, u: np.ndarray, t: int) -> np.ndarray:
        """The true plant's next states ``A x + B u`` (+ the disturbance at step ``t``)."""
        xn = x @ self.A.T + u @ self.B.T
        return xn if self.noise is None else xn + self.noise.w[t]

    def rows(self, active: np.ndarray) -> np.ndarray:
        """Rows of the live-model arrays (``F``, ``f``, the condensed QPs) of realisations ``active``."""
        return self.pos[active]

    def track(self) -> None:
        """Follow ``w.reference`` with preview (the controllers were built for a zero reference)."""
        self.condensed()
        cs = [self.ctrls[i] for i in self.live]
        free = (np.stack([c.A for c in cs]), np.stack([c.B for c in cs]), self.w.R) if self.offset_free else None
        self.preview = Preview(self.cq, self.F.shape[1], self.w.reference, free)

    def ref_offsets(self, j: np.ndarray, t: int, H: int):
        """The reference part of the prediction map at steps ``t..t+H-1`` (0 without a time-varying reference)."""
        return 0.0 if self.preview is None else self.preview.offsets(j, t, H)

    def stage_cost(self, xs: np.ndarray, us: np.ndarray, t: int = 0) -> np.ndarray:
        """``(x - r)'Q(x - r) + u'R u`` over the last axis (``xs`` from step ``t``)."""
        # a time-varying reference runs along the time axis (second to last) from step t
        e = xs - (self.w.x_ref if self.preview is None else self.preview.r[t : t + xs.shape[-2]])
        return np.einsum("...i,ij,...j->...", e, self.w.Q, e) + np.einsum("...i,ij,...j->...", us, self.w.R, us)

    def fail(self, i: int, kind: FailureKind, msg: str) -> None:
        self.out.failure[i], self.out.messages[i] = kind, msg
        self.out.states[i] = np.nan
        self.out.inputs[i] = np.nan

    def speculate(self, active: np.ndarray, t: int) -> tuple[np.ndarray, int]:
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
        n, m, out = self.n, self.m, self.out
        j = self.rows(active)
        Fu, fu = self.F[j, :m], self.f[j, :m]
        Mcl = self.A[None] + np.einsum("ij,ljk->lik", self.B, Fu)
        ccl = fu @ self.B.T
        H = self.steps - t
        xs = np.empty((active.size, H + 1, n))
        xs[:, 0] = self.x[active]
        if self.noise is None and self.preview is None:
            for h in range(H):
                xs[:, h + 1] = np.einsum("lij,lj->li", Mcl, xs[:, h]) + ccl
            z = np.einsum("lrn,lhn->lhr", self.F[j], xs[:, :H]) + self.f[j][:, None, :]
        else:  # the law acts on what the controller measures and previews; the true plant may be disturbed
            z = np.zeros((active.size, H, self.f.shape[1])) + self.ref_offsets(j, t, H)
            for h in range(H):
                z[:, h] += np.einsum("lrn,ln->lr", self.F[j], self.seen(xs[:, h], t + h)) + self.f[j]
                xs[:, h + 1] = self.moved(xs[:, h], z[:, h, :m], t + h)
        ok = np.all(np.abs(z) <= self.bound, axis=2)
        ok &= np.all(np.isfinite(xs[:, 1:]), axis=2) & (np.abs(xs[:, 1:]).max(axis=2) <= DIVERGED)
        first_bad = np.where(ok.all(axis=1), H, np.argmin(ok, axis=1))
        if t == 0:
            y0 = self.seen(xs[:, 0], 0)
            for a, i in enumerate(active):
                if first_bad[a] > 0:
                    out.J0[i] = self.first_cost(i, y0[a], z[a, 0, : self.nU])
        tau = int(first_bad.min())
        done = first_bad == H
        us = z[:, :, :m]
        for a, i in enumerate(active):
            k = H if done[a] else tau
            if k:
                out.states[i, t + 1 : t + k + 1] = xs[a, 1 : k + 1]
                out.inputs[i, t : t + k] = us[a, :k]
                self.acc[i] += self.stage_cost(xs[a, :k], us[a, :k], t).sum()
                self.x[i] = xs[a, k]
        return active[~done], t + tau

    def first_cost(self, i: int, y: np.ndarray, U: np.ndarray) -> float:
        """``J*(x0)`` of loop ``i``'s first problem from its unconstrained optimum ``U``."""
        c = self.ctrls[i]
        if self.preview is None:
            return c.cost_to_go(y)
        self.preview.set_qp(c._qp, self.pos[i], 0)
        return c.qp_cost(y, U)

    def condensed(self, attach: bool = True) -> None:
        """Condense the QPs of all live models in one batch (once) and, with ``attach``, hand them to the
        controllers (the compiled loop attaches a model only when its DAQP solver is needed: :meth:`attach`)."""
        if self.cq is not None:
            return
        cs = [self.ctrls[i] for i in self.live]
        c0 = cs[0]
        self.cq = condense(
            np.stack([c.A for c in cs]),
            np.stack([c.B for c in cs]),
            c0.Q,
            c0.R,
            np.stack([c.Qf for c in cs]),
            c0.x_ref,
            c0.N,
        )
        if attach:
            for k, c in enumerate(cs):
                c.use_condensed(self.cq, k)

    def attach(self, i: int) -> None:
        """Hand realisation ``i``'s condensed QP to its controller (for its DAQP solver)."""
        self.condensed(attach=False)
        self.ctrls[i].use_condensed(self.cq, int(self.pos[i]))

    def solve_slow(self, idx: np.ndarray, xs: np.ndarray, zs: np.ndarray, t: int) -> tuple[np.ndarray, np.ndarray]:
        """``u_0`` of the models ``idx`` (states ``xs``) whose unconstrained optimum ``zs`` violates a bound.

        Box-only DAQP problems are first solved all at once by a few primal-dual
        active-set iterations (:func:`box_qp_batch`) from a guess: the previous
        step's active set shifted by one step (receding horizon), or at the first
        constrained step the bounds the unconstrained optimum violates. Where that
        does not settle -- and for state boxes or OSQP -- the model's own solver is
        called (DAQP warm-starts from its last active set). Failures are recorded.
        Returns ``(u (S, m), solved (S,))``.
        """
        m, ub = self.m, self.ub
        self.out.qp_steps += idx.size
        if self.solver_is_daqp:
            self.condensed()
        u = np.empty((idx.size, m))
        todo = np.ones(idx.size, dtype=bool)
        if self.guess:
            j = self.rows(idx)
            g = np.einsum("lij,lj->li", self.cq.Gx[j], xs) + self.cq.g0[j]
            if self.preview is not None:
                g += self.preview.g(j, t)
            prev = self.prevU[idx]
            shifted = np.concatenate([prev[:, m:], prev[:, -m:]], axis=1)
            fresh = (self.prev_t[idx] != t - 1)[:, None]  # no solution at the previous step: guess afresh
            base = np.where(fresh, zs[:, : ub.size], shifted)
            hi, lo = base >= ub * (1 - 1e-9), base <= -ub * (1 - 1e-9)
            U, ok = box_qp_batch(self.cq.H[j], g, ub, hi, lo)
            self.prevU[idx[ok]] = U[ok]
            self.prev_t[idx[ok]] = t
            u[ok] = U[ok, :m]
            todo = ~ok
        solved = np.ones(idx.size, dtype=bool)
        for a in np.flatnonzero(todo):
            i, c = int(idx[a]), self.ctrls[int(idx[a])]
            if self.preview is not None:
                self.preview.set_qp(c._qp, self.pos[i], t)
            try:
                if c.solver == "daqp":
                    U = c.solve_daqp(xs[a])
                    self.prevU[i], self.prev_t[i], u[a] = U, t, U[:m]
                else:
                    u[a], J = c.solve_qp(xs[a])
                    if t == 0:
                        self.out.J0[i] = J
            except MPCFailure as exc:
                self.fail(i, exc.kind, f"step {t}: {exc}")
                solved[a] = False
        if t == 0 and self.solver_is_daqp:  # the predicted optimal cost J*(x0) of the first problem
            for a in np.flatnonzero(solved):
                c = self.ctrls[int(idx[a])]
                if self.preview is not None:
                    self.preview.set_qp(c._qp, self.pos[idx[a]], 0)
                self.out.J0[idx[a]] = c.qp_cost(xs[a], self.prevU[idx[a]])
        # the active set meets the bounds up to rounding: clip that rounding
        return np.clip(u, -self.w.u_max, self.w.u_max), solved

    def step_small(self, active: np.ndarray, t: int) -> tuple[np.ndarray, bool]:
        """:meth:`step` for a few models, one at a time: the same law, the QP by the model's own solver."""
        m, out = self.m, self.out
        keep, all_fast = [], True
        for i in active:
            c, x = self.ctrls[i], self.x[i]
            y = self.seen(x[None], t)[0]
            z = c.F @ y + c.f
            if self.preview is not None:
                z = z + self.preview.offsets(self.pos[[i]], t, 1)[0, 0]
                self.preview.set_qp(c._qp, self.pos[i], t)
            fast = bool(np.all(np.abs(z) <= c.bound))
            try:
                if fast:
                    u, J = z[:m], (self.first_cost(i, y, z[: self.nU]) if t == 0 else np.nan)
                else:
                    out.qp_steps += 1
                    u, J = c.solve_qp(y)
            except MPCFailure as exc:
                self.fail(i, exc.kind, f"step {t}: {exc}")
                continue
            if t == 0:
                out.J0[i] = J
            xn = self.moved(x[None], np.asarray(u)[None], t)[0]  # the true plant moves
            if not np.all(np.isfinite(xn)) or np.abs(xn).max() > DIVERGED:
                self.fail(i, FailureKind.DIVERGED, f"closed loop diverged at step {t + 1}")
                continue
            out.states[i, t + 1], out.inputs[i, t] = xn, u
            self.acc[i] += self.stage_cost(x[None], np.asarray(u)[None], t)[0]
            self.x[i] = xn
            keep.append(i)
            all_fast &= fast
        return np.array(keep, dtype=int), all_fast

    def step(self, active: np.ndarray, t: int) -> tuple[np.ndarray, bool]:
        """One closed-loop step of every active model; the QP solver only where a bound is active.

        Returns the models still running and whether all of them took the fast path
        (then the caller goes back to :meth:`speculate`).
        """
        j = self.rows(active)
        xi = self.x[active]
        yi = self.seen(xi, t)
        z1 = np.einsum("lrn,ln->lr", self.F[j], yi) + self.f[j]
        if self.preview is not None:
            z1 += self.preview.offsets(j, t, 1)[:, 0]
        fast_ok = np.all(np.abs(z1) <= self.bound, axis=1)
        u = z1[:, : self.m].copy()
        keep = np.ones(active.size, dtype=bool)
        slow = np.flatnonzero(~fast_ok)
        if slow.size:
            u[slow], ok = self.solve_slow(active[slow], yi[slow], z1[slow], t)
            keep[slow] = ok
        if t == 0:
            for a in np.flatnonzero(fast_ok):
                self.out.J0[active[a]] = self.first_cost(int(active[a]), yi[a], z1[a, : self.nU])
        xn = self.moved(xi, u, t)  # the true plant moves: x+ = A x + B u (+ w)
        bad = ~np.all(np.isfinite(xn), axis=1) | (np.abs(xn).max(axis=1) > DIVERGED)
        for a in np.flatnonzero(bad & keep):
            self.fail(int(active[a]), FailureKind.DIVERGED, f"closed loop diverged at step {t + 1}")
            keep[a] = False
        sel = active[keep]
        self.out.states[sel, t + 1] = xn[keep]
        self.out.inputs[sel, t] = u[keep]
        self.acc[sel] += (
            self.stage_cost(xi[keep], u[keep], t)
            if self.preview is None
            else self.stage_cost(xi[keep][:, None], u[keep][:, None], t)[:, 0]
        )
        self.x[sel] = xn[keep]
        return sel, bool(fast_ok[keep].all())


def run_closed_loops(
    models, A_true: np.ndarray, B_true: np.ndarray, cfg: MPCConfig, system, feedback_range: tuple | None = None
) -> ClosedLoops:
    """Run the MPC built on each model ``(A^, B^)`` in closed loop on the true system.

    Exact and fast: while the unconstrained LQ optimum is feasible, the MPC law
    is the affine feedback ``u = F_u x + f_u``, so the closed loop is simulated
    ahead for all models at once and every predicted constraint is checked in
    one batch. Models stay on that path until their first step where a
    constraint would be violated; from there on they are stepped one step at a
    time, with the QP solver (``cfg.solver``) on the steps where a bound is
    active, until a step where every remaining model is back on the fast path.
    A failure (no model, no DARE solution, infeasible QP, iteration limit,
    diverging state) is recorded for that model and never raised.

    Parameters
    ----------
    models : sequence of (A_hat, B_hat)
        Identified models, shapes (n, n) and (n, m); non-finite entries mean "no model".
    A_true, B_true : ndarray, shapes (n, n), (n, m)
        The true plant the inputs are applied to.
    cfg : MPCConfig
    system : LTISystem
        Supplies default Q, R and x0 (see :meth:`MPCConfig.resolve`).
    feedback_range : (lo, hi, guard), optional
        The training data's state range, for ``cfg.feedback_bits`` (:mod:`qsid_core.control.loop_noise`).
        With a disturbance or a quantized/noisy measurement the verdicts are those of
        the same MPC on the noise-free plant (the law's stability), except that a
        loop whose disturbed run diverged is ``diverged``.

    Returns
    -------
    ClosedLoops
    """
    w = cfg.resolve(system)
    n, m = B_true.shape
    Rn, steps = len(models), cfg.steps
    out = ClosedLoops.empty(Rn, steps, n, m)
    out.x_ref = w.x_ref
    ctrls = build_controllers(models, w, cfg, out.failure, out.messages)
    if all(c is None for c in ctrls):
        if cfg.verify_steps is not None:
            out.outcome = ["failed"] * Rn
            out.spectral_radius = np.full(Rn, np.nan)
            out.verdict_steps = np.zeros(Rn, dtype=int)
            out.gains = [None] * Rn
        return out
    noise = loop_noise(cfg, n, steps, feedback_range)
    loops = _Loops(ctrls, w, np.asarray(A_true, float), np.asarray(B_true, float), steps, out, noise=noise)
    if w.reference is not None:
        loops.offset_free = cfg.tracking == "offset-free"
        loops.track()
        out.x_ref = w.reference[: steps + 1]
    advance(loops, loops.live.copy())
    ok = np.array([not fl for fl in out.failure])
    out.cost[ok] = loops.acc[ok]
    out.J0[~ok] = np.nan
    if cfg.verify_steps is None:
        return out
    if noise is None and w.reference is None:
        judge(loops, cfg.verify_steps, _extender(loops))
    else:
        clean = run_closed_loops(models, A_true, B_true, cfg.nominal(), system)
        out.outcome = ["diverged" if f == FailureKind.DIVERGED else o for f, o in zip(out.failure, clean.outcome)]
        out.spectral_radius, out.verdict_steps, out.gains = clean.spectral_radius, clean.verdict_steps, clean.gains
    return out


def _extender(loops: _Loops):
    """``extend(x, k, active)``: run the loops ``active`` on from states ``x`` for ``k`` more steps.

    Returns the extra steps' :class:`ClosedLoops` and the states reached; the
    condensed QPs are shared with ``loops`` (built once).
    """

    def extend(x: np.ndarray, k: int, active: list) -> tuple[ClosedLoops, np.ndarray]:
        scratch = ClosedLoops.empty(len(loops.ctrls), k, loops.n, loops.m)
        ext = _Loops(loops.ctrls, loops.w, loops.A, loops.B, k, scratch, x_start=x, cq=loops.cq)
        advance(ext, np.array(active))
        loops.cq = ext.cq
        return scratch, ext.x

    return extend


def advance(loops: _Loops, active: np.ndarray) -> None:
    """Run the loops ``active`` for ``loops.steps`` steps: the fast path ahead, one step at a time where a bound is active."""
    if eligible(loops):  # box-only DAQP, exact feedback: the whole loop compiled
        run_compiled(loops, active, DIVERGED, loops.first_costs)
        return
    t, steps = 0, loops.steps
    with np.errstate(over="ignore", invalid="ignore"):
        while t < steps and active.size:
            active, t = loops.speculate(active, t)
            while t < steps and active.size:
                active, all_fast = (loops.step_small if active.size <= SMALL else loops.step)(active, t)
                t += 1
                if all_fast:
                    break
