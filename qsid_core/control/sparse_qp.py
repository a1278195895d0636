"""The MPC's QP in sparse form, solved by OSQP: the previous engine, kept as a reference.

Variables ``z = [x_0; ...; x_N; u_0; ...; u_{N-1}]``; the dynamics are equality
rows, the initial-state row's bounds are set to the measured state each step and
OSQP warm-starts from the previous solution. :class:`qsid_core.control.controller.MPCController`
uses it for ``solver="osqp"``; the default is DAQP on the condensed problem
(:mod:`qsid_core.control.condensed_qp`), which is exact and about 10x faster per solve.

Note: OSQP installs its own SIGINT handler around every solve (and restores the
previous one after), so a Ctrl-C can be lost when solves run in threads.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import FailureKind, MPCFailure
from .riccati import state_box

__all__ = ["OsqpMPC"]


class OsqpMPC:
    """One model's sparse MPC QP in a warm-started OSQP workspace.

    Parameters
    ----------
    A, B : ndarray, shapes (n, n), (n, m)
        The identified model.
    Q, R, Qf : ndarray, shapes (n, n), (m, m), (n, n)
    x_ref : ndarray, shape (n,)
    N : int
        Horizon.
    u_max : ndarray, shape (m,); x_max, xf_max : ndarray, shape (n,), or None
    eps : float
        Absolute and relative tolerance.
    max_iter : int
    """

    def __init__(
        self,
        A: np.ndarray,
        B: np.ndarray,
        Q: np.ndarray,
        R: np.ndarray,
        Qf: np.ndarray,
        x_ref: np.ndarray,
        N: int,
        u_max: np.ndarray,
        x_max: np.ndarray | None,
        xf_max: np.ndarray | None,
        eps: float,
        max_iter: int,
    ) -> None:
        self.A, self.B, self.Q, self.R, self.Qf, self.x_ref = A, B, Q, R, Qf, x_ref
        self.n, self.m = B.shape
        self.N, self.u_max, self.x_max, self.xf_max = N, u_max, x_max, xf_max
        self.eps, self.max_iter = eps, max_iter
        self._setup_osqp()

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
        bx = state_box(n, N, self.x_max, self.xf_max)
        if bx is not None:
            rows.append(sp.hstack([sp.csc_matrix((N * n, n)), sp.eye(N * n), sp.csc_matrix((N * n, N * m))]))
            lo.append(-bx)
            hi.append(bx)
        self._l = np.concatenate(lo)
        self._u = np.concatenate(hi)
        Aall = sp.vstack(rows, format="csc")
        prob = osqp.OSQP()
        prob.setup(
            sp.triu(P, format="csc"),
            q,
            Aall,
            self._l,
            self._u,
            verbose=False,
            polishing=True,
            warm_starting=True,
            eps_abs=self._coarse or self.eps,
            eps_rel=self._coarse or self.eps,
            max_iter=self.max_iter,
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

    def _polished(self, res: Any) -> bool:
        import osqp

        return bool(
            res.info.status_val == osqp.SolverStatus.OSQP_SOLVED
            and res.info.status_polish == 1
            and max(res.info.prim_res, res.info.dual_res) <= self.eps
        )

    def solve(self, x: np.ndarray) -> tuple[np.ndarray, float]:
        """Solve the QP with OSQP from state ``x``; returns ``(u_0, J*)``.

        Raises
        ------
        MPCFailure
            kind ``"infeasible"``, ``"max_iter"`` or ``"solver"`` when OSQP does not solve it.
        """
        import osqp

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
            raise MPCFailure(FailureKind.INFEASIBLE, "MPC problem is infeasible from the current state")
        if st == S.OSQP_MAX_ITER_REACHED:
            raise MPCFailure(FailureKind.MAX_ITER, f"OSQP reached its iteration limit ({self.max_iter})")
        if st not in (S.OSQP_SOLVED, S.OSQP_SOLVED_INACCURATE):
            raise MPCFailure(FailureKind.SOLVER, f"OSQP failed: {res.info.status}")
        N1 = (self.N + 1) * n
        u0 = np.clip(res.x[N1 : N1 + self.m], -self.u_max, self.u_max)
        # OSQP minimises 1/2 z'Pz + q'z: our P, q are the cost's halves, so J = 2 obj + r-terms
        return u0, 2.0 * float(res.info.obj_val) + self._const
