"""Closed loops: the MPC built on each identified model, run on the true system.

:func:`run_closed_loops` runs many models at once. While the unconstrained LQ
optimum is feasible the MPC law is an affine feedback, so the loop is simulated
ahead and every predicted constraint checked in one batch; steps where a bound
is active are solved by OSQP (:class:`qsid_core.mpc.MPCController`). Failures
are recorded per model, never raised.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import MPCFailure
from .mpc import MPCConfig, MPCController
from .riccati import dare_batch, lq_parts

__all__ = ["ClosedLoops", "run_closed_loops"]


@dataclass
class ClosedLoops:
    """Closed loops of several identified models, each run on the true system.

    Attributes
    ----------
    states : ndarray, shape (R, steps + 1, n)
        True-system trajectories (NaN after a failure).
    inputs : ndarray, shape (R, steps, m)
    cost : ndarray, shape (R,)
        Realised cost ``sum_{t<steps} (x_t-r)'Q(x_t-r) + u_t'R u_t`` on the true system (NaN if failed).
    J0 : ndarray, shape (R,)
        Predicted optimal cost ``J*(x0)`` of the first MPC problem (NaN if failed).
    failure : list of str
        ``""`` for success, else a kind from :data:`FAILURE_KINDS`.
    messages : list of str
        Plain-words reason per failed realisation.
    osqp_steps : int
        How many MPC steps needed OSQP (the rest took the exact fast path).
    """

    states: np.ndarray
    inputs: np.ndarray
    cost: np.ndarray
    J0: np.ndarray
    failure: list = field(default_factory=list)
    messages: list = field(default_factory=list)
    osqp_steps: int = 0

    @property
    def failed(self) -> np.ndarray:
        return np.array([bool(f) for f in self.failure])

    @property
    def final_state_norm(self) -> np.ndarray:
        return np.linalg.norm(self.states[:, -1, :], axis=1)


def run_closed_loops(models, A_true: np.ndarray, B_true: np.ndarray, cfg: MPCConfig, system) -> ClosedLoops:
    """Run the MPC built on each model ``(A^, B^)`` in closed loop on the true system.

    Exact and fast: while the unconstrained LQ optimum is feasible, the MPC law
    is the affine feedback ``u = F_u x + f_u``, so the closed loop is simulated
    ahead for all models at once and every predicted constraint is checked in
    one batch. Models stay on that path until their first step where a
    constraint would be violated; from there on they are stepped one step at a
    time, with OSQP solving the steps where a bound is active, until a step
    where every remaining model is back on the fast path. A failure (no model,
    no DARE solution, infeasible QP, iteration limit, diverging state) is
    recorded for that model and never raised.

    Parameters
    ----------
    models : sequence of (A_hat, B_hat)
    A_true, B_true : ndarray
        The true plant the inputs are applied to.
    cfg : MPCConfig
    system : LTISystem
        Supplies default Q, R and x0 (see :meth:`MPCConfig.resolve`).
    """
    w = cfg.resolve(system)
    n, m = B_true.shape
    Rn = len(models)
    steps = cfg.steps
    states = np.full((Rn, steps + 1, n), np.nan)
    inputs = np.full((Rn, steps, m), np.nan)
    cost = np.full(Rn, np.nan)
    J0 = np.full(Rn, np.nan)
    failure = [""] * Rn
    messages = [""] * Rn
    # models without finite entries (failed identifications) are left to MPCController to reject
    fi = [i for i, (a, b) in enumerate(models) if np.all(np.isfinite(a)) and np.all(np.isfinite(b))]
    Qfs: list = [w["Qf"]] * Rn
    if w["Qf"] is None and fi:
        # terminal weights of all models at once; the few that SDA cannot settle go to scipy
        X, okd = dare_batch(np.stack([models[i][0] for i in fi]), np.stack([models[i][1] for i in fi]),
                            w["Q"], w["R"])
        for k, i in enumerate(fi):
            if okd[k]:
                Qfs[i] = X[k]
    # fast-path gains and prediction maps of every model with a terminal weight, in one batch
    ready = [i for i in fi if Qfs[i] is not None]
    batch: dict = {}
    if ready:
        with np.errstate(all="ignore"):
            bp = lq_parts(np.stack([np.asarray(models[i][0], float) for i in ready]),
                          np.stack([np.asarray(models[i][1], float) for i in ready]), w["Q"], w["R"],
                          np.stack([np.asarray(Qfs[i], float) for i in ready]), w["x_ref"], cfg.horizon,
                          w["u_max"], w["x_max"], w["xf_max"])
        for k, i in enumerate(ready):
            pk = {key: (v[k] if key != "bound" else v) for key, v in bp.items()}
            if all(np.all(np.isfinite(v)) for key, v in pk.items() if key != "bound"):
                batch[i] = pk
    ctrls: list[MPCController | None] = []
    for i, (Ah, Bh) in enumerate(models):
        try:
            ctrls.append(MPCController(Ah, Bh, w["Q"], w["R"], cfg.horizon, w["u_max"], w["x_max"], w["xf_max"],
                                       w["x_ref"], Qfs[i], cfg.eps, cfg.max_iter, parts=batch.get(i)))
        except MPCFailure as exc:
            ctrls.append(None)
            failure[i], messages[i] = exc.kind, str(exc)
    live = np.array([c is not None for c in ctrls], dtype=bool)
    if not live.any():
        return ClosedLoops(states, inputs, cost, J0, failure, messages, 0)
    Q, R, r = w["Q"], w["R"], w["x_ref"]
    lid = np.flatnonzero(live)
    F = np.stack([ctrls[i].F for i in lid])  # (L, rows, n)
    f = np.stack([ctrls[i].f for i in lid])  # (L, rows)
    bound = ctrls[lid[0]].bound
    pos = {int(i): j for j, i in enumerate(lid)}
    acc = np.zeros(Rn)
    x = np.tile(w["x0"], (Rn, 1))
    states[lid, 0] = x[lid]
    osqp_steps = 0

    def fail(i: int, kind: str, msg: str) -> None:
        failure[i], messages[i] = kind, msg
        states[i] = np.nan
        inputs[i] = np.nan

    def stage_cost(xs: np.ndarray, us: np.ndarray) -> np.ndarray:
        e = xs - r
        return np.einsum("...i,ij,...j->...", e, Q, e) + np.einsum("...i,ij,...j->...", us, R, us)

    active = lid.copy()
    t = 0
    with np.errstate(over="ignore", invalid="ignore"):
        while t < steps and active.size:
            # --- speculate: fast-path feedback for the remaining steps, checked in one batch
            j = np.array([pos[int(i)] for i in active])
            Fu, fu = F[j, :m], f[j, :m]
            Mcl = A_true[None] + np.einsum("ij,ljk->lik", B_true, Fu)
            ccl = fu @ B_true.T
            H = steps - t
            xs = np.empty((active.size, H + 1, n))
            xs[:, 0] = x[active]
            for h in range(H):
                xs[:, h + 1] = np.einsum("lij,lj->li", Mcl, xs[:, h]) + ccl
            z = np.einsum("lrn,lhn->lhr", F[j], xs[:, :H]) + f[j][:, None, :]
            ok = np.all(np.abs(z) <= bound, axis=2)
            ok &= np.all(np.isfinite(xs[:, 1:]), axis=2) & (np.abs(xs[:, 1:]).max(axis=2) <= 1e12)
            first_bad = np.where(ok.all(axis=1), H, np.argmin(ok, axis=1))
            if t == 0:
                for a, i in enumerate(active):
                    if first_bad[a] > 0:
                        J0[i] = ctrls[i].cost_to_go(xs[a, 0])
            tau = int(first_bad.min())
            done = first_bad == H
            # commit the valid prefix: everything for models that never leave the fast path
            us = z[:, :, :m]
            for a, i in enumerate(active):
                k = H if done[a] else tau
                if k:
                    states[i, t + 1 : t + k + 1] = xs[a, 1 : k + 1]
                    inputs[i, t : t + k] = us[a, :k]
                    acc[i] += stage_cost(xs[a, :k], us[a, :k]).sum()
                    x[i] = xs[a, k]
            active = active[~done]
            t += tau
            # --- step one at a time until every remaining model is back on the fast path
            while t < steps and active.size:
                j = np.array([pos[int(i)] for i in active])
                xi = x[active]
                z1 = np.einsum("lrn,ln->lr", F[j], xi) + f[j]
                fast_ok = np.all(np.abs(z1) <= bound, axis=1)
                u = z1[:, :m].copy()
                keep = np.ones(active.size, dtype=bool)
                for a in np.flatnonzero(~fast_ok):
                    i = int(active[a])
                    osqp_steps += 1
                    try:
                        u[a], Jt = ctrls[i].solve_osqp(xi[a])
                        if t == 0:
                            J0[i] = Jt
                    except MPCFailure as exc:
                        fail(i, exc.kind, f"step {t}: {exc}")
                        keep[a] = False
                if t == 0:
                    for a in np.flatnonzero(fast_ok):
                        J0[active[a]] = ctrls[active[a]].cost_to_go(xi[a])
                xn = xi @ A_true.T + u @ B_true.T
                bad = ~np.all(np.isfinite(xn), axis=1) | (np.abs(xn).max(axis=1) > 1e12)
                for a in np.flatnonzero(bad & keep):
                    fail(int(active[a]), "diverged", f"closed loop diverged at step {t + 1}")
                    keep[a] = False
                sel = active[keep]
                states[sel, t + 1] = xn[keep]
                inputs[sel, t] = u[keep]
                acc[sel] += stage_cost(xi[keep], u[keep])
                x[sel] = xn[keep]
                all_fast = bool(fast_ok[keep].all())
                active = sel
                t += 1
                if all_fast:
                    break
    ok_all = np.array([not fl for fl in failure])
    cost[ok_all] = acc[ok_all]
    J0[~ok_all] = np.nan
    return ClosedLoops(states, inputs, cost, J0, failure, messages, osqp_steps)
