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

__all__ = [
    "MPCConfig", "MPCFailure", "MPCController", "ClosedLoops", "run_closed_loops", "FAILURE_KINDS", "dare_batch",
    "dare_stabilizing", "lq_parts",
]

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


def dare_batch(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, tol: float = 1e-13,
               max_iter: int = 80) -> tuple[np.ndarray, np.ndarray]:
    """Stabilizing DARE solutions for a batch of models, by structure-preserving doubling.

    Parameters
    ----------
    A : ndarray, shape (L, n, n)
    B : ndarray, shape (L, n, m)
    Q : ndarray, shape (n, n)
    R : ndarray, shape (m, m), positive definite

    Returns
    -------
    X : ndarray, shape (L, n, n)
        The solutions (NaN where ``ok`` is False).
    ok : ndarray of bool, shape (L,)
        Converged, finite and stabilizing (spectral radius of ``A - B K`` below 1).
        Callers fall back to :func:`dare_stabilizing` where it is False.

    Notes
    -----
    SDA (Chu, Fan, Lin 2005): ``A_0 = A``, ``G_0 = B R^-1 B'``, ``H_0 = Q``;
    ``W = I + G_k H_k``; ``A_{k+1} = A_k W^-1 A_k``, ``G_{k+1} = G_k + A_k W^-1 G_k A_k'``,
    ``H_{k+1} = H_k + A_k' H_k W^-1 A_k``; ``H_k`` converges quadratically to the
    stabilizing solution. All models are iterated together with batched numpy.
    """
    L, n, _ = A.shape
    Ak = np.array(A, dtype=float)
    G = B @ np.linalg.solve(R, np.swapaxes(B, 1, 2))
    H = np.broadcast_to(np.asarray(Q, dtype=float), (L, n, n)).copy()
    I = np.eye(n)
    done = np.zeros(L, dtype=bool)
    with np.errstate(all="ignore"):
        for _ in range(max_iter):
            W = I + G @ H
            try:
                WiA = np.linalg.solve(W, Ak)
                WiG = np.linalg.solve(W, G)
            except np.linalg.LinAlgError:
                break
            Hn = H + np.swapaxes(Ak, 1, 2) @ H @ WiA
            G = G + Ak @ WiG @ np.swapaxes(Ak, 1, 2)
            Ak = Ak @ WiA
            delta = np.abs(Hn - H).max(axis=(1, 2))
            scale = np.abs(Hn).max(axis=(1, 2))
            H = Hn
            done = np.isfinite(delta) & (delta <= tol * np.maximum(scale, 1.0))
            if done.all():
                break
        X = (H + np.swapaxes(H, 1, 2)) / 2
        ok = done & np.all(np.isfinite(X), axis=(1, 2))
        if ok.any():
            Bt = np.swapaxes(B, 1, 2)
            K = np.linalg.solve(R + Bt @ X @ B, Bt @ X @ A)
            Acl = np.where(ok[:, None, None], A - B @ K, 0.0)
            rho = np.abs(np.linalg.eigvals(Acl)).max(axis=1)
            ok &= rho < 1.0
    X[~ok] = np.nan
    return X, ok


def lq_parts(A, B, Q, R, Qf, r, N, u_max, x_max=None, xf_max=None) -> dict:
    """Unconstrained finite-horizon LQ solution for a batch of models (the MPC's fast path).

    Backward Riccati recursion with an affine term for the reference ``r``:
    ``u_k = -K_k x_k - kf_k``; ``V_0(x) = x'P0x + 2 p0'x + c0``. Then the affine map
    ``z = F x0 + f`` from the initial state to the predicted inputs ``u_0..u_{N-1}``
    (and, with a state or terminal box, states ``x_1..x_N``) with the box
    half-widths ``bound``: the unconstrained optimum solves the constrained QP
    exactly iff ``|F x0 + f| <= bound``.

    Parameters
    ----------
    A : (L, n, n), B : (L, n, m), Qf : (L, n, n)
        Models and terminal weights.
    Q : (n, n), R : (m, m), r : (n,)
    N : int
        Horizon.
    u_max : (m,); x_max, xf_max : (n,) or None

    Returns
    -------
    dict with K (L,N,m,n), kf (L,N,m), P0 (L,n,n), p0 (L,n), c0 (L,), F (L,rows,n), f (L,rows), bound (rows,)
    """
    L, n, m = B.shape
    At, Bt = np.swapaxes(A, 1, 2), np.swapaxes(B, 1, 2)
    P = np.array(Qf, dtype=float)
    p = -(P @ r)
    c = np.einsum("i,lij,j->l", r, P, r)
    rQr = float(r @ Q @ r)
    K = np.empty((L, N, m, n))
    kf = np.empty((L, N, m))
    for k in range(N - 1, -1, -1):
        BtP = Bt @ P
        S = R + BtP @ B
        Kk = np.linalg.solve(S, BtP @ A)
        Btp = np.einsum("lij,lj->li", Bt, p)
        kk = np.linalg.solve(S, Btp[..., None])[..., 0]
        c = c + rQr - np.einsum("li,li->l", Btp, kk)
        p = -(Q @ r) + np.einsum("lji,lj->li", A - B @ Kk, p)
        P = Q + At @ P @ A - np.swapaxes(BtP @ A, 1, 2) @ Kk
        P = (P + np.swapaxes(P, 1, 2)) / 2
        K[:, k], kf[:, k] = Kk, kk
    Mx = np.broadcast_to(np.eye(n), (L, n, n))
    mx = np.zeros((L, n))
    Fu, fu, Fx, fx = [], [], [], []
    for k in range(N):
        Fk = -K[:, k] @ Mx
        fk = -np.einsum("lij,lj->li", K[:, k], mx) - kf[:, k]
        Mx = A @ Mx + B @ Fk
        mx = np.einsum("lij,lj->li", A, mx) + np.einsum("lij,lj->li", B, fk)
        Fu.append(Fk)
        fu.append(fk)
        Fx.append(Mx)
        fx.append(mx)
    F, f, bound = list(Fu), list(fu), [np.asarray(u_max, dtype=float)] * N
    if x_max is not None or xf_max is not None:
        big = np.full(n, np.inf)
        boxes = [np.asarray(x_max, dtype=float) if x_max is not None else big for _ in range(N)]
        if xf_max is not None:
            boxes[-1] = np.minimum(boxes[-1], xf_max)
        F += Fx
        f += fx
        bound += boxes
    return dict(K=K, kf=kf, P0=P, p0=p, c0=c, F=np.concatenate(F, axis=1), f=np.concatenate(f, axis=1),
                bound=np.concatenate(bound))


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
                 eps: float = 1e-9, max_iter: int = 20000, parts: dict | None = None):
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
        if parts is None:
            self._riccati()
        else:  # computed for a batch of models by run_closed_loops
            self._set_parts(parts)
        self._osqp = None

    # ----- fast path -----------------------------------------------------------------
    def _riccati(self) -> None:
        """Gains and value function of the unconstrained problem, and its prediction map."""
        parts = lq_parts(self.A[None], self.B[None], self.Q, self.R, self.Qf[None], self.x_ref, self.N,
                         self.u_max, self.x_max, self.xf_max)
        self._set_parts({k: v[0] if k != "bound" else v for k, v in parts.items()})

    def _set_parts(self, parts: dict) -> None:
        self.K, self.kf = parts["K"], parts["kf"]
        self.P0, self.p0, self.c0 = parts["P0"], parts["p0"], float(parts["c0"])
        self.F, self.f, self.bound = parts["F"], parts["f"], parts["bound"]

    def cost_to_go(self, x: np.ndarray) -> float:
        """Unconstrained optimal cost ``x'P0x + 2p0'x + c0`` (equals J*(x) when the fast path holds)."""
        return float(x @ self.P0 @ x + 2 * self.p0 @ x + self.c0)

    def fast(self, x: np.ndarray) -> tuple[np.ndarray, float] | None:
        """Unconstrained LQ optimum ``(u_0, J*)`` if it satisfies every constraint, else None."""
        xs = np.asarray(x, dtype=float)
        z = self.F @ xs + self.f
        if not np.all(np.abs(z) <= self.bound):
            return None
        return z[: self.m], self.cost_to_go(xs)

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
            eps_abs=self._coarse or self.eps, eps_rel=self._coarse or self.eps, max_iter=self.max_iter,
        )
        self._osqp = prob
        self._nz = nz
        self._const = float(N * self.x_ref @ self.Q @ self.x_ref + self.x_ref @ self.Qf @ self.x_ref)

    #: ADMM tolerance of the first solve; polishing then solves the KKT system of the
    #: guessed active set exactly, and the result is kept only if its residuals are
    #: below ``eps`` (else OSQP continues to ``eps``). Same answer, fewer iterations.
    COARSE_EPS = 1e-3

    @property
    def _coarse(self) -> float:
        return self.COARSE_EPS if self.eps < self.COARSE_EPS else 0.0

    def _polished(self, res) -> bool:
        import osqp

        return (
            res.info.status_val == osqp.SolverStatus.OSQP_SOLVED
            and res.info.status_polish == 1
            and max(res.info.prim_res, res.info.dual_res) <= self.eps
        )

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
        if self._coarse and not self._polished(res):
            # the coarse solve's polished active set was not exact: solve again to eps (warm-started)
            self._osqp.update_settings(eps_abs=self.eps, eps_rel=self.eps)
            res = self._osqp.solve(raise_error=False)
            self._osqp.update_settings(eps_abs=self._coarse, eps_rel=self._coarse)
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
    Qfs: list = [w["Qf"]] * Rn
    if w["Qf"] is None and Rn:
        # terminal weights of all models at once; the few that SDA cannot settle go to scipy
        finite = [bool(np.all(np.isfinite(a)) and np.all(np.isfinite(b))) for a, b in models]
        fi = [i for i in range(Rn) if finite[i]]
        if fi:
            X, okd = dare_batch(np.stack([models[i][0] for i in fi]), np.stack([models[i][1] for i in fi]),
                                w["Q"], w["R"])
            for k, i in enumerate(fi):
                if okd[k]:
                    Qfs[i] = X[k]
    # fast-path gains and prediction maps of every model with a terminal weight, in one batch
    ready = [i for i in range(Rn) if Qfs[i] is not None and np.all(np.isfinite(models[i][0]))
             and np.all(np.isfinite(models[i][1]))]
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
