"""Linear MPC on an identified model, run in closed loop on the true system.

The letter's problem (eq. (2)) with horizon ``Th``::

    min  sum_{k<Th} (x_k - r)'Q(x_k - r) + u_k'R u_k + (x_Th - r)'Qf(x_Th - r)
    s.t. x_{k+1} = A^ x_k + B^ u_k,  x_0 = measured state,
         |u_k| <= u_max,  |x_k| <= x_max (k = 1..Th, optional),  |x_Th| <= xf_max (optional)

``Qf`` defaults to the DARE solution of ``(A^, B^, Q, R)``. The state box is
never put on ``x_0`` (the measured state): with model mismatch that could make
the problem infeasible.

Two exact solution paths:

* **fast path** -- the unconstrained finite-horizon LQ solution (backward
  Riccati recursion with an affine term for the reference). If its predicted
  inputs and states satisfy every constraint it *is* the optimum of the convex
  QP, and OSQP is skipped.
* **OSQP** -- the sparse QP, set up once per identified model; each step only the
  bounds of the initial-state equality are updated and the solver warm-starts.
  The status is checked every step.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from .errors import ConfigError, QsidError, check_float, check_int

__all__ = ["MPCConfig", "MPCFailure", "MPCController", "ClosedLoops", "run_closed_loops", "FAILURE_KINDS"]

FAILURE_KINDS = ("ident", "dare", "infeasible", "max_iter", "solver", "diverged")


class MPCFailure(QsidError):
    """The MPC could not be built or solved; ``kind`` is one of :data:`FAILURE_KINDS`."""

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind = kind


def _vec(name: str, v, k: int | None, positive: bool = False) -> tuple[float, ...] | None:
    if v is None:
        return None
    arr = np.atleast_1d(np.asarray(v, dtype=float)).reshape(-1)
    if not np.all(np.isfinite(arr)):
        raise ConfigError(f"{name} must contain finite numbers; got {v!r}")
    if positive and np.any(arr <= 0):
        raise ConfigError(f"{name} must be positive; got {v!r}")
    if k is not None and arr.size not in (1, k):
        raise ConfigError(f"{name} must have 1 or {k} entries; got {arr.size}")
    return tuple(arr.tolist())


@dataclass(frozen=True)
class MPCConfig:
    """MPC settings (unset weights and x0 come from the system's defaults).

    Parameters
    ----------
    horizon : int, 1..200
        Prediction horizon ``Th`` (default 10, the letter's).
    steps : int, 1..10000
        Closed-loop steps on the true system (``mpc_steps``, default 50).
    u_max : float or tuple, > 0
        Input box ``|u_i| <= u_max_i`` (default 1).
    x_max : float or tuple, optional
        State box on ``x_1 .. x_Th`` (never on the measured ``x_0``).
    xf_max : float or tuple, optional
        Terminal box on ``x_Th``.
    Q, R : tuple of floats, optional
        Diagonals of the weights (default: the system's Q and R).
    Qf : tuple of floats, optional
        Diagonal of the terminal weight (default: DARE solution for the model).
    x0 : tuple of floats, optional
        Initial state (default: the system's x0).
    x_ref : tuple of floats, optional
        Constant reference (default 0).
    eps : float
        OSQP absolute and relative tolerance (default 1e-9, tight so that
        inputs do not overshoot their bound; the result is clipped as well).
    max_iter : int
        OSQP iteration limit.
    """

    horizon: int = 10
    steps: int = 50
    u_max: float | tuple = 1.0
    x_max: float | tuple | None = None
    xf_max: float | tuple | None = None
    Q: tuple | None = None
    R: tuple | None = None
    Qf: tuple | None = None
    x0: tuple | None = None
    x_ref: tuple | None = None
    eps: float = 1e-9
    max_iter: int = 20000

    def __post_init__(self) -> None:
        check_int("horizon", self.horizon, 1, 200)
        check_int("mpc steps", self.steps, 1, 10000)
        check_float("OSQP eps", self.eps, 0.0, 1e-2, lo_open=True)
        check_int("max_iter", self.max_iter, 1)
        object.__setattr__(self, "u_max", _vec("u_max", self.u_max, None, positive=True))
        object.__setattr__(self, "x_max", _vec("x_max", self.x_max, None, positive=True))
        object.__setattr__(self, "xf_max", _vec("xf_max", self.xf_max, None, positive=True))
        for nm in ("Q", "R", "Qf", "x0", "x_ref"):
            object.__setattr__(self, nm, _vec(nm, getattr(self, nm), None))
        for nm in ("Q", "Qf"):
            v = getattr(self, nm)
            if v is not None and min(v) < 0:
                raise ConfigError(f"{nm} diagonal must be >= 0; got {v}")
        if self.R is not None and min(self.R) <= 0:
            raise ConfigError(f"R diagonal must be > 0; got {self.R}")

    def resolve(self, system) -> dict:
        """Weights, bounds and x0 as arrays for ``system`` (shapes checked)."""
        n, m = system.n, system.m

        def full(name, v, k, default):
            if v is None:
                return default
            arr = np.asarray(v, dtype=float)
            if arr.size == 1:
                arr = np.repeat(arr, k)
            if arr.size != k:
                raise ConfigError(f"{name} must have 1 or {k} entries for system {system.name!r}; got {arr.size}")
            return arr

        Q = np.diag(full("Q", self.Q, n, None)) if self.Q is not None else np.array(system.Q)
        R = np.diag(full("R", self.R, m, None)) if self.R is not None else np.array(system.R)
        return dict(
            Q=Q,
            R=R,
            Qf=None if self.Qf is None else np.diag(full("Qf", self.Qf, n, None)),
            x0=full("x0", self.x0, n, np.array(system.x0)),
            x_ref=full("x_ref", self.x_ref, n, np.zeros(n)),
            u_max=full("u_max", self.u_max, m, None),
            x_max=None if self.x_max is None else full("x_max", self.x_max, n, None),
            xf_max=None if self.xf_max is None else full("xf_max", self.xf_max, n, None),
        )


def dare_stabilizing(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Stabilizing solution of the DARE for ``(A, B, Q, R)``.

    Raises
    ------
    MPCFailure (kind "dare")
        If there is none (e.g. an identified model that is not stabilizable).
    """
    try:
        with np.errstate(all="ignore"):
            X = sla.solve_discrete_are(A, B, Q, R)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise MPCFailure("dare", f"DARE has no stabilizing solution for the identified model ({exc})") from None
    if not np.all(np.isfinite(X)):
        raise MPCFailure("dare", "DARE has no stabilizing solution for the identified model")
    X = (X + X.T) / 2
    K = np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A)
    if np.abs(np.linalg.eigvals(A - B @ K)).max() >= 1.0 or np.linalg.eigvalsh(X).min() < -1e-9:
        raise MPCFailure("dare", "DARE solution is not stabilizing for the identified model")
    return X


class MPCController:
    """The letter's MPC for one identified model ``(A^, B^)``: fast path plus OSQP.

    Parameters
    ----------
    A_hat : ndarray, shape (n, n)
    B_hat : ndarray, shape (n, m)
    Q, R : ndarray
        Stage weights, ``R`` positive definite.
    horizon : int
    u_max : ndarray, shape (m,)
    x_max, xf_max : ndarray, shape (n,), or None
    x_ref : ndarray, shape (n,)
    Qf : ndarray, optional
        Terminal weight; default: DARE solution for ``(A^, B^, Q, R)``.

    Raises
    ------
    MPCFailure
        kind ``"dare"`` if Qf is not given and the DARE has no stabilizing solution.
    """

    def __init__(self, A_hat, B_hat, Q, R, horizon, u_max, x_max=None, xf_max=None, x_ref=None, Qf=None,
                 eps: float = 1e-9, max_iter: int = 20000):
        self.A = np.asarray(A_hat, dtype=float)
        self.B = np.asarray(B_hat, dtype=float)
        self.n, self.m = self.B.shape
        self.Q = np.asarray(Q, dtype=float)
        self.R = np.asarray(R, dtype=float)
        self.N = int(horizon)
        self.u_max = np.asarray(u_max, dtype=float)
        self.x_max = None if x_max is None else np.asarray(x_max, dtype=float)
        self.xf_max = None if xf_max is None else np.asarray(xf_max, dtype=float)
        self.x_ref = np.zeros(self.n) if x_ref is None else np.asarray(x_ref, dtype=float)
        self.eps = eps
        self.max_iter = max_iter
        if not (np.all(np.isfinite(self.A)) and np.all(np.isfinite(self.B))):
            raise MPCFailure("ident", "no model: identification failed for this realization")
        self.Qf = dare_stabilizing(self.A, self.B, self.Q, self.R) if Qf is None else np.asarray(Qf, dtype=float)
        self._riccati()
        self._osqp = None

    # ----- fast path -----------------------------------------------------------------
    def _riccati(self) -> None:
        """Backward recursion: u_k = -K_k x_k - k_k; V_0(x) = x'P0x + 2p0'x + c0."""
        A, B, Q, R, r = self.A, self.B, self.Q, self.R, self.x_ref
        P = self.Qf.copy()
        p = -self.Qf @ r
        c = float(r @ self.Qf @ r)
        K = np.empty((self.N, self.m, self.n))
        kf = np.empty((self.N, self.m))
        for k in range(self.N - 1, -1, -1):
            BtP = B.T @ P
            S = R + BtP @ B
            Kk = np.linalg.solve(S, BtP @ A)
            kk = np.linalg.solve(S, B.T @ p)
            c = c + float(r @ Q @ r) - float((B.T @ p) @ kk)
            p = -Q @ r + (A - B @ Kk).T @ p
            P = Q + A.T @ P @ A - (BtP @ A).T @ Kk
            P = (P + P.T) / 2
            K[k], kf[k] = Kk, kk
        self.K, self.kf, self.P0, self.p0, self.c0 = K, kf, P, p, c

    def fast(self, x: np.ndarray) -> tuple[np.ndarray, float] | None:
        """Unconstrained LQ optimum ``(u_0, J*)`` if it satisfies every constraint, else None."""
        xs = np.asarray(x, dtype=float)
        xk = xs
        u0 = None
        for k in range(self.N):
            u = -self.K[k] @ xk - self.kf[k]
            if np.any(np.abs(u) > self.u_max):
                return None
            if u0 is None:
                u0 = u
            xk = self.A @ xk + self.B @ u
            box = self.x_max
            if k == self.N - 1 and self.xf_max is not None:
                box = self.xf_max if box is None else np.minimum(box, self.xf_max)
            if box is not None and np.any(np.abs(xk) > box):
                return None
        J = float(xs @ self.P0 @ xs + 2 * self.p0 @ xs + self.c0)
        return u0, J

    # ----- OSQP ----------------------------------------------------------------------
    def _setup_osqp(self) -> None:
        import osqp

        n, m, N = self.n, self.m, self.N
        A, B = self.A, self.B
        P = sp.block_diag([sp.kron(sp.eye(N), self.Q), self.Qf, sp.kron(sp.eye(N), self.R)], format="csc")
        q = np.concatenate([np.kron(np.ones(N), -self.Q @ self.x_ref), -self.Qf @ self.x_ref, np.zeros(N * m)])
        Ax = sp.kron(sp.eye(N + 1), -sp.eye(n)) + sp.kron(sp.eye(N + 1, k=-1), A)
        Bu = sp.kron(sp.vstack([sp.csc_matrix((1, N)), sp.eye(N)]), B)
        Aeq = sp.hstack([Ax, Bu])
        nz = (N + 1) * n + N * m
        rows = [Aeq]
        lo = [np.zeros((N + 1) * n)]
        hi = [np.zeros((N + 1) * n)]
        # input box
        rows.append(sp.hstack([sp.csc_matrix((N * m, (N + 1) * n)), sp.eye(N * m)]))
        lo.append(np.tile(-self.u_max, N))
        hi.append(np.tile(self.u_max, N))
        # state box on x_1..x_N (not on x_0), terminal box on x_N
        if self.x_max is not None or self.xf_max is not None:
            big = np.full(n, np.inf)
            boxes = [self.x_max if self.x_max is not None else big for _ in range(N)]
            if self.xf_max is not None:
                boxes[-1] = np.minimum(boxes[-1], self.xf_max)
            bx = np.concatenate(boxes)
            rows.append(sp.hstack([sp.csc_matrix((N * n, n)), sp.eye(N * n), sp.csc_matrix((N * n, N * m))]))
            lo.append(-bx)
            hi.append(bx)
        self._l = np.concatenate(lo)
        self._u = np.concatenate(hi)
        Aall = sp.vstack(rows, format="csc")
        prob = osqp.OSQP()
        prob.setup(
            sp.triu(P, format="csc"), q, Aall, self._l, self._u, verbose=False, polishing=True, warm_starting=True,
            eps_abs=self.eps, eps_rel=self.eps, max_iter=self.max_iter,
        )
        self._osqp = prob
        self._nz = nz
        self._const = float(N * self.x_ref @ self.Q @ self.x_ref + self.x_ref @ self.Qf @ self.x_ref)

    def solve_osqp(self, x: np.ndarray) -> tuple[np.ndarray, float]:
        """Solve the QP with OSQP from state ``x``; returns ``(u_0, J*)``.

        Raises
        ------
        MPCFailure
            kind ``"infeasible"``, ``"max_iter"`` or ``"solver"`` when OSQP does not solve it.
        """
        import osqp

        if self._osqp is None:
            self._setup_osqp()
        n = self.n
        self._l[:n] = -x
        self._u[:n] = -x
        self._osqp.update(l=self._l, u=self._u)
        res = self._osqp.solve(raise_error=False)
        st = res.info.status_val
        S = osqp.SolverStatus
        if st in (S.OSQP_PRIMAL_INFEASIBLE, S.OSQP_PRIMAL_INFEASIBLE_INACCURATE):
            raise MPCFailure("infeasible", "MPC problem is infeasible from the current state")
        if st == S.OSQP_MAX_ITER_REACHED:
            raise MPCFailure("max_iter", f"OSQP reached its iteration limit ({self.max_iter})")
        if st not in (S.OSQP_SOLVED, S.OSQP_SOLVED_INACCURATE):
            raise MPCFailure("solver", f"OSQP failed: {res.info.status}")
        N1 = (self.N + 1) * n
        u0 = np.clip(res.x[N1 : N1 + self.m], -self.u_max, self.u_max)
        # OSQP minimises 1/2 z'Pz + q'z: our P, q are the cost's halves, so J = 2 obj + r-terms
        return u0, 2.0 * float(res.info.obj_val) + self._const

    def solve(self, x: np.ndarray) -> tuple[np.ndarray, float, bool]:
        """``(u_0, J*, used_fast_path)`` for state ``x``."""
        f = self.fast(x)
        if f is not None:
            return f[0], f[1], True
        u, J = self.solve_osqp(x)
        return u, J, False


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

    The exact fast path is evaluated for all models at once (batched); models
    whose unconstrained optimum violates a constraint at a step use OSQP for
    that step. A failure (no DARE solution, infeasible QP, iteration limit,
    diverging state) is recorded for that model and never raised.

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
    steps, N = cfg.steps, cfg.horizon
    states = np.full((Rn, steps + 1, n), np.nan)
    inputs = np.full((Rn, steps, m), np.nan)
    cost = np.full(Rn, np.nan)
    J0 = np.full(Rn, np.nan)
    failure = [""] * Rn
    messages = [""] * Rn
    ctrls: list[MPCController | None] = []
    for i, (Ah, Bh) in enumerate(models):
        try:
            ctrls.append(MPCController(Ah, Bh, w["Q"], w["R"], N, w["u_max"], w["x_max"], w["xf_max"],
                                       w["x_ref"], w["Qf"], cfg.eps, cfg.max_iter))
        except MPCFailure as exc:
            ctrls.append(None)
            failure[i], messages[i] = exc.kind, str(exc)
    alive = np.array([c is not None for c in ctrls])
    idx = np.flatnonzero(alive)
    x = np.tile(w["x0"], (Rn, 1))
    states[idx, 0] = x[idx]
    acc = np.zeros(Rn)
    r = w["x_ref"]
    Q, R = w["Q"], w["R"]
    # stacked model and gains of the live controllers
    if idx.size:
        Ab = np.stack([ctrls[i].A for i in idx])
        Bb = np.stack([ctrls[i].B for i in idx])
        Kb = np.stack([ctrls[i].K for i in idx])  # (L, N, m, n)
        kb = np.stack([ctrls[i].kf for i in idx])  # (L, N, m)
        P0 = np.stack([ctrls[i].P0 for i in idx])
        p0 = np.stack([ctrls[i].p0 for i in idx])
        c0 = np.array([ctrls[i].c0 for i in idx])
    box_x = w["x_max"]
    box_f = w["xf_max"]
    if box_f is not None:
        box_f = box_f if box_x is None else np.minimum(box_x, box_f)
    else:
        box_f = box_x
    osqp_steps = 0
    for t in range(steps):
        if idx.size == 0:
            break
        xi = x[idx]
        # batched fast path over the live controllers
        ok = np.ones(idx.size, dtype=bool)
        xk = xi
        u_first = None
        for k in range(N):
            u = -np.einsum("lij,lj->li", Kb[:, k], xk) - kb[:, k]
            ok &= np.all(np.abs(u) <= w["u_max"], axis=1)
            if u_first is None:
                u_first = u
            xk = np.einsum("lij,lj->li", Ab, xk) + np.einsum("lij,lj->li", Bb, u)
            box = box_f if k == N - 1 else box_x
            if box is not None:
                ok &= np.all(np.abs(xk) <= box, axis=1)
        u_apply = u_first.copy()
        Jt = np.einsum("li,lij,lj->l", xi, P0, xi) + 2 * np.einsum("li,li->l", p0, xi) + c0
        keep = np.ones(idx.size, dtype=bool)
        for j in np.flatnonzero(~ok):
            i = idx[j]
            osqp_steps += 1
            try:
                u_apply[j], Jt[j] = ctrls[i].solve_osqp(xi[j])
            except MPCFailure as exc:
                failure[i], messages[i] = exc.kind, f"step {t}: {exc}"
                keep[j] = False
        if t == 0:
            J0[idx[keep]] = Jt[keep]
        if not keep.all():
            states[idx[~keep]] = np.nan
            inputs[idx[~keep]] = np.nan
            sel = keep
            idx, xi, u_apply = idx[sel], xi[sel], u_apply[sel]
            Ab, Bb, Kb, kb, P0, p0, c0 = Ab[sel], Bb[sel], Kb[sel], kb[sel], P0[sel], p0[sel], c0[sel]
            if idx.size == 0:
                break
        e = xi - r
        acc[idx] += np.einsum("li,ij,lj->l", e, Q, e) + np.einsum("li,ij,lj->l", u_apply, R, u_apply)
        xn = xi @ A_true.T + u_apply @ B_true.T
        inputs[idx, t] = u_apply
        states[idx, t + 1] = xn
        x[idx] = xn
        bad = ~np.all(np.isfinite(xn), axis=1) | (np.abs(xn).max(axis=1) > 1e12)
        if bad.any():
            for j in np.flatnonzero(bad):
                failure[idx[j]], messages[idx[j]] = "diverged", f"closed loop diverged at step {t + 1}"
                states[idx[j]] = np.nan
                inputs[idx[j]] = np.nan
            sel = ~bad
            idx = idx[sel]
            Ab, Bb, Kb, kb, P0, p0, c0 = Ab[sel], Bb[sel], Kb[sel], kb[sel], P0[sel], p0[sel], c0[sel]
    ok_all = np.array([not f for f in failure])
    cost[ok_all] = acc[ok_all]
    return ClosedLoops(states, inputs, cost, J0, failure, messages, osqp_steps)
