"""Linear MPC on an identified model (run in closed loop by :mod:`qsid_core.closed_loop`).

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

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .errors import ConfigError, MPCFailure, check_float, check_int
from .validate import as_float_array
from .riccati import dare_batch, dare_stabilizing, lq_parts

__all__ = ["MPCConfig", "MPCFailure", "MPCController", "FAILURE_KINDS", "dare_batch", "dare_stabilizing", "lq_parts"]

FAILURE_KINDS = ("ident", "dare", "infeasible", "max_iter", "solver", "diverged")
#: OSQP's setup error codes in words.
OSQP_SETUP_ERRORS = {1: "invalid problem data", 2: "invalid settings", 3: "linear system solver failed",
                     4: "the cost is not convex: a weight is not positive semidefinite", 5: "out of memory"}


def _vec(name: str, v, k: int | None, positive: bool = False) -> tuple[float, ...] | None:
    if v is None:
        return None
    arr = np.atleast_1d(as_float_array(name, v, ndim_max=1)).reshape(-1)  # finite, <= MAX_MAGNITUDE, not empty
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
        with np.errstate(all="ignore"):
            parts = lq_parts(self.A[None], self.B[None], self.Q, self.R, self.Qf[None], self.x_ref, self.N,
                             self.u_max, self.x_max, self.xf_max)
        if not all(np.all(np.isfinite(v)) for k, v in parts.items() if k != "bound"):
            raise MPCFailure("dare", "the finite-horizon Riccati recursion of the identified model is singular or "
                                     "overflows: no MPC for this model")
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
            try:
                self._setup_osqp()
            except (ValueError, osqp.OSQPException) as exc:  # OSQP rejects the data (e.g. Qf numerically not PSD)
                raise MPCFailure("solver", f"OSQP cannot set up the MPC problem for this model "
                                           f"({OSQP_SETUP_ERRORS.get(exc.args[0] if exc.args else 0, exc)})") from None
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


