"""The MPC of one identified model: :class:`MPCController` (settings: :class:`~qsid_core.control.mpc.MPCConfig`).

Exact solution paths:

* **fast path** -- the unconstrained finite-horizon LQ solution (backward
  Riccati recursion with an affine term for the reference). If its predicted
  inputs and states satisfy every constraint it *is* the optimum of the convex
  QP, and no solver is called.
* **DAQP** (default, ``solver="daqp"``) -- the QP condensed onto the ``N m``
  inputs (:mod:`qsid_core.control.condensed_qp`): input box as simple bounds, state and
  terminal boxes as general rows; a dual active-set solver, warm-started from
  the previous step's active set. Never calls OSQP.
* **OSQP** (``solver="osqp"``, the previous engine, kept as a reference and for
  the benchmarks) -- the sparse QP, set up once per identified model; each step
  only the bounds of the initial-state equality are updated and it warm-starts.

The solver's status is checked every step; failures raise :class:`MPCFailure`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..errors import FailureKind, MPCFailure, check_choice
from .condensed_qp import CondensedQP, DaqpMPC, condense
from .mpc import SOLVERS
from .riccati import LQParts, dare_stabilizing, lq_parts, state_box

if TYPE_CHECKING:
    from .sparse_qp import OsqpMPC  # imported when first used: it loads OSQP

__all__ = ["MPCController", "OSQP_SETUP_ERRORS"]

#: OSQP's setup error codes in words.
OSQP_SETUP_ERRORS = {
    1: "invalid problem data",
    2: "invalid settings",
    3: "linear system solver failed",
    4: "the cost is not convex: a weight is not positive semidefinite",
    5: "out of memory",
}


class MPCController:
    """The letter's MPC for one identified model ``(A^, B^)``: fast path plus a QP solver.

    Parameters
    ----------
    A_hat : ndarray, shape (n, n)
    B_hat : ndarray, shape (n, m)
    Q : ndarray, shape (n, n); R : ndarray, shape (m, m)
        Stage weights, ``R`` positive definite.
    horizon : int
    u_max : ndarray, shape (m,)
    x_max, xf_max : ndarray, shape (n,), or None
    x_ref : ndarray, shape (n,)
    Qf : ndarray, shape (n, n), optional
        Terminal weight; default: DARE solution for ``(A^, B^, Q, R)``.
    eps : float
        OSQP tolerance (``solver="osqp"`` only).
    max_iter : int
        QP solver iteration limit.
    parts : LQParts, optional
        This model's fast-path parts, if already computed for a batch (:func:`lq_parts`).
    solver : {"daqp", "osqp"}

    Raises
    ------
    MPCFailure
        kind ``ident`` if the model is not finite; ``dare`` if Qf is not given and
        the DARE has no stabilizing solution.
    """

    def __init__(
        self,
        A_hat: ArrayLike,
        B_hat: ArrayLike,
        Q: ArrayLike,
        R: ArrayLike,
        horizon: int,
        u_max: ArrayLike,
        x_max: ArrayLike | None = None,
        xf_max: ArrayLike | None = None,
        x_ref: ArrayLike | None = None,
        Qf: ArrayLike | None = None,
        eps: float = 1e-9,
        max_iter: int = 20000,
        parts: LQParts | None = None,
        solver: str = "daqp",
    ) -> None:
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
        self.solver = check_choice("solver", solver, SOLVERS)
        if not (np.all(np.isfinite(self.A)) and np.all(np.isfinite(self.B))):
            raise MPCFailure(FailureKind.IDENT, "no model: identification failed for this realization")
        self.Qf = dare_stabilizing(self.A, self.B, self.Q, self.R) if Qf is None else np.asarray(Qf, dtype=float)
        if parts is None:
            with np.errstate(all="ignore"):
                batch = lq_parts(
                    self.A[None],
                    self.B[None],
                    self.Q,
                    self.R,
                    self.Qf[None],
                    self.x_ref,
                    self.N,
                    self.u_max,
                    self.x_max,
                    self.xf_max,
                )
            if not batch.finite()[0]:
                raise MPCFailure(
                    FailureKind.DARE,
                    "the finite-horizon Riccati recursion of the identified model is "
                    "singular or overflows: no MPC for this model",
                )
            parts = batch.model(0)
        self.parts = parts
        self.F, self.f, self.bound = parts.F, parts.f, parts.bound
        self._qp: DaqpMPC | None = None
        self._osqp: OsqpMPC | None = None

    # ----- fast path -----------------------------------------------------------------
    def cost_to_go(self, x: np.ndarray) -> float:
        """Unconstrained optimal cost ``x'P0x + 2p0'x + c0`` (equals J*(x) when the fast path holds)."""
        p = self.parts
        return float(x @ p.P0 @ x + 2 * p.p0 @ x + p.c0)

    def fast(self, x: np.ndarray) -> tuple[np.ndarray, float] | None:
        """Unconstrained LQ optimum ``(u_0, J*)`` if it satisfies every constraint, else None."""
        xs = np.asarray(x, dtype=float)
        z = self.F @ xs + self.f
        if not np.all(np.abs(z) <= self.bound):
            return None
        return z[: self.m], self.cost_to_go(xs)

    # ----- QP solvers ----------------------------------------------------------------
    def use_condensed(self, cq: CondensedQP, k: int) -> None:
        """Use model ``k`` of a batch-condensed problem for the DAQP solves (saves condensing it alone)."""
        if self.solver == "daqp" and self._qp is None:
            self._qp = DaqpMPC(
                cq, k, self.Q, self.x_ref, self.u_max, state_box(self.n, self.N, self.x_max, self.xf_max), self.max_iter
            )

    def daqp(self) -> DaqpMPC:
        """The condensed problem DAQP solves for this model (condensed alone on first use, unless a batch
        handed it over through :meth:`use_condensed`)."""
        if self._qp is None:
            cq = condense(self.A[None], self.B[None], self.Q, self.R, self.Qf[None], self.x_ref, self.N)
            self._qp = DaqpMPC(
                cq, 0, self.Q, self.x_ref, self.u_max, state_box(self.n, self.N, self.x_max, self.xf_max), self.max_iter
            )
        return self._qp

    def solve_qp(self, x: np.ndarray) -> tuple[np.ndarray, float]:
        """Solve the constrained QP from state ``x`` with the configured solver; returns ``(u_0, J*)``.

        Raises
        ------
        MPCFailure
            kind ``infeasible``, ``max_iter`` or ``solver``.
        """
        if self.solver == "osqp":
            return self.solve_osqp(x)
        x = np.asarray(x, dtype=float)
        U = self.solve_daqp(x)
        return np.clip(U[: self.m], -self.u_max, self.u_max), self.qp_cost(x, U)

    def solve_daqp(self, x: np.ndarray) -> np.ndarray:
        """The optimal input sequence ``U = [u_0; ...; u_{N-1}]``, shape (N*m,), by DAQP (no clipping)."""
        return self.daqp().solve(x)

    def qp_cost(self, x: np.ndarray, U: np.ndarray) -> float:
        """MPC cost ``J(U; x)`` of the input sequence ``U`` (shape (N*m,)) from state ``x`` (condensed form)."""
        return self.daqp().cost(np.asarray(x, dtype=float), U)

    def solve_osqp(self, x: np.ndarray) -> tuple[np.ndarray, float]:
        """Solve the QP with OSQP on the sparse formulation (the previous engine); ``(u_0, J*)``."""
        if self._osqp is None:
            import osqp

            from .sparse_qp import OsqpMPC

            try:
                self._osqp = OsqpMPC(
                    self.A,
                    self.B,
                    self.Q,
                    self.R,
                    self.Qf,
                    self.x_ref,
                    self.N,
                    self.u_max,
                    self.x_max,
                    self.xf_max,
                    self.eps,
                    self.max_iter,
                )
            except (ValueError, osqp.OSQPException) as exc:  # OSQP rejects the data (e.g. Qf numerically not PSD)
                raise MPCFailure(
                    FailureKind.SOLVER,
                    f"OSQP cannot set up the MPC problem for this model "
                    f"({OSQP_SETUP_ERRORS.get(exc.args[0] if exc.args else 0, exc)})",
                ) from None
        return self._osqp.solve(x)

    def solve(self, x: np.ndarray) -> tuple[np.ndarray, float, bool]:
        """``(u_0, J*, used_fast_path)`` for state ``x``."""
        f = self.fast(x)
        if f is not None:
            return f[0], f[1], True
        u, J = self.solve_qp(x)
        return u, J, False
