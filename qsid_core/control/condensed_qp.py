"""The MPC problem condensed onto the input sequence, solved by DAQP (dual active set).

Eliminating the predicted states with ``x_{k} = A^k x_0 + sum_{j<k} A^{k-1-j} B u_j``
turns the letter's QP (eq. (2)) into a dense problem in ``U = [u_0; ...; u_{N-1}]``
(``N m`` variables)::

    X = [x_1; ...; x_N] = Sx x_0 + Su U
    J(U; x_0) = U' H U + 2 g(x_0)' U + c(x_0)
    H    = Su' Qbar Su + Rbar                   Qbar = blkdiag(Q, ..., Q, Qf),  Rbar = blkdiag(R, ..., R)
    g    = Su' Qbar (Sx x_0 - rbar)              rbar = [r; ...; r]
    c    = (Sx x_0 - rbar)' Qbar (Sx x_0 - rbar) + (x_0 - r)' Q (x_0 - r)

subject to ``|u_k| <= u_max`` (simple bounds) and, optionally,
``|x_k| <= x_max`` (k = 1..N) and ``|x_N| <= xf_max``: general rows
``-box - Sx x_0 <= Su U <= box - Sx x_0``. ``H`` is positive definite (``R`` is),
so the problem is strictly convex and the active-set solution is exact up to
rounding once the active set is right.

DAQP (Arnström, Bemporad, Axehill 2022) is a dual active-set solver made for
such small dense MPC problems; a :class:`DaqpMPC` keeps one ``daqp.Model`` per
identified model so each closed-loop step only updates ``g`` and the bounds and
starts from the previous step's active set (warm start).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import FailureKind, MPCFailure

__all__ = ["CondensedQP", "condense", "DaqpMPC"]

#: DAQP exit flags (include/constants.h of DAQP): 1 optimal, 2 soft optimal, -1 infeasible,
#: -2 cycling, -3 unbounded, -4 iteration limit; anything else negative is a solver failure.
_OPTIMAL, _INFEASIBLE, _ITERLIMIT = 1, -1, -4


@dataclass(frozen=True)
class CondensedQP:
    """The condensed MPC problem of a batch of ``L`` models (see the module docstring).

    Attributes
    ----------
    H : ndarray, shape (L, N*m, N*m)
        Hessian ``Su' Qbar Su + Rbar`` (cost units per input unit squared).
    Gx : ndarray, shape (L, N*m, n)
        ``g = Gx x_0 + g0`` with ``Gx = Su' Qbar Sx``.
    g0 : ndarray, shape (L, N*m)
        ``-Su' Qbar rbar``.
    Sx : ndarray, shape (L, N*n, n)
        Free response: predicted states ``x_1..x_N`` for ``U = 0``.
    Su : ndarray, shape (L, N*n, N*m)
        Forced response (block lower triangular, ``A^{k-1-j} B`` blocks).
    Qbars : ndarray, shape (L, N*n, N*n)
        Weights of ``x_1..x_N`` per model: ``blkdiag(Q, ..., Q, Qf)`` (for ``c(x_0)``).
    Gr : ndarray, shape (L, N*m, N*n)
        ``-Su' Qbar``: a reference ``rbar = [r_1; ...; r_N]`` over the horizon adds ``Gr rbar`` to ``g``.
    """

    H: np.ndarray
    Gx: np.ndarray
    g0: np.ndarray
    Sx: np.ndarray
    Su: np.ndarray
    Qbars: np.ndarray
    Gr: np.ndarray | None = None


def condense(
    A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, Qf: np.ndarray, r: np.ndarray, N: int
) -> CondensedQP:
    """Condense the horizon-``N`` MPC problem of each model onto its input sequence.

    Parameters
    ----------
    A : ndarray, shape (L, n, n)
    B : ndarray, shape (L, n, m)
    Q : ndarray, shape (n, n); R : ndarray, shape (m, m)
    Qf : ndarray, shape (L, n, n)
        Terminal weight per model.
    r : ndarray, shape (n,)
        Constant reference.
    N : int
        Horizon.
    """
    A = np.asarray(A, float)
    B = np.asarray(B, float)
    L, n, m = B.shape
    # Sx = [A; A^2; ...; A^N];  block (k, j) of Su = A^{k-j} B for j <= k (rows x_{k+1}, columns u_j)
    Sx = np.empty((L, N * n, n))
    Su = np.zeros((L, N * n, N * m))
    Ak = np.broadcast_to(np.eye(n), (L, n, n))
    AkB = [B]  # A^0 B, A^1 B, ...
    for k in range(N):
        Ak = A @ Ak
        Sx[:, k * n : (k + 1) * n] = Ak
        if k:
            AkB.append(A @ AkB[-1])
    for k in range(N):
        for j in range(k + 1):
            Su[:, k * n : (k + 1) * n, j * m : (j + 1) * m] = AkB[k - j]
    # Qbar per model (the last block is that model's Qf)
    Qbars = np.zeros((L, N * n, N * n))
    for k in range(N - 1):
        Qbars[:, k * n : (k + 1) * n, k * n : (k + 1) * n] = Q
    Qbars[:, (N - 1) * n :, (N - 1) * n :] = Qf
    SuT_Qbar = np.swapaxes(Su, 1, 2) @ Qbars
    H = SuT_Qbar @ Su + np.kron(np.eye(N), R)
    H = (H + np.swapaxes(H, 1, 2)) / 2
    Gx = SuT_Qbar @ Sx
    g0 = -SuT_Qbar @ np.tile(np.asarray(r, float), N)
    return CondensedQP(H=H, Gx=Gx, g0=g0, Sx=Sx, Su=Su, Qbars=Qbars, Gr=-SuT_Qbar)


class DaqpMPC:
    """One model's condensed MPC problem, solved by a warm-started ``daqp.Model``.

    Parameters
    ----------
    cq : CondensedQP
        Condensed problem of a batch; ``k`` selects this model.
    k : int
    Q : ndarray, shape (n, n)
    r : ndarray, shape (n,)
    u_max : ndarray, shape (m,)
        Input box half-widths (simple bounds on every ``u_k``).
    x_box : ndarray, shape (N*n,), or None
        Half-widths of the state box on ``x_1..x_N`` (``inf`` where unbounded);
        only finite entries become constraint rows.
    max_iter : int
        DAQP iteration limit.
    """

    def __init__(
        self,
        cq: CondensedQP,
        k: int,
        Q: ArrayLike,
        r: ArrayLike,
        u_max: ArrayLike,
        x_box: np.ndarray | None = None,
        max_iter: int = 20000,
    ) -> None:
        self.H = np.ascontiguousarray(cq.H[k])
        self.Gx, self.g0 = cq.Gx[k], cq.g0[k]
        self.Sx, self.Qbar = cq.Sx[k], cq.Qbars[k]
        self.Q = np.asarray(Q, float)
        self.r = np.asarray(r, float)
        nU = self.H.shape[0]
        self.u_max = np.asarray(u_max, float)
        self.m = self.u_max.size
        self.N = nU // self.m
        self.rbar = np.tile(self.r, self.N)
        ub = np.tile(self.u_max, self.N)
        if x_box is not None:
            rows = np.flatnonzero(np.isfinite(x_box))
            self._xrows, self._xbox = rows, np.asarray(x_box, float)[rows]
            self.Arows = np.ascontiguousarray(cq.Su[k][rows])
        else:
            self._xrows, self._xbox = np.zeros(0, int), np.zeros(0)
            self.Arows = np.zeros((0, nU))
        nc = self._xrows.size
        self._bu = np.concatenate([ub, np.zeros(nc)])
        self._bl = np.concatenate([-ub, np.zeros(nc)])
        self._sense = np.zeros(nU + nc, dtype=np.int32)
        self.max_iter = int(max_iter)
        self._model: Any = None  # the daqp.Model, made by the first solve
        self.g_ref = 0.0  # with a time-varying reference: its part of g at the current step (set by the caller)
        self.c_ref = 0.0  # ... and of the cost's constant (offset-free form: u_ref'R u_ref terms)

    def _bounds(self, x0: np.ndarray) -> None:
        """State rows: ``-box - (Sx x0)_i <= (Su U)_i <= box - (Sx x0)_i``."""
        if self._xrows.size:
            free = self.Sx[self._xrows] @ x0
            nU = self.H.shape[0]
            self._bu[nU:] = self._xbox - free
            self._bl[nU:] = -self._xbox - free

    def solve(self, x0: np.ndarray) -> np.ndarray:
        """Optimal input sequence ``U`` (shape (N*m,)) from state ``x0`` (shape (n,), float).

        Warm start: the ``daqp.Model`` keeps the previous solve's active set, and only
        ``g(x0)`` (and, with a state box, the bounds of its rows) is updated.

        Raises
        ------
        MPCFailure
            kind ``infeasible`` (state box cannot be met), ``max_iter`` or ``solver``.
        """
        g = self.Gx @ x0 + self.g0 + self.g_ref
        if self._model is None:
            self._setup(x0, g)
        elif self._xrows.size:
            self._bounds(x0)
            self._model.update(f=g, bupper=self._bu, blower=self._bl)
        else:
            self._model.update(f=g)
        U: np.ndarray
        U, _, flag, _ = self._model.solve()
        if flag != _OPTIMAL:
            self._raise(flag)
        return U

    def _setup(self, x0: np.ndarray, g: np.ndarray) -> None:
        import daqp

        self._bounds(x0)
        self._model = daqp.Model()
        # exact active-set solves: tight primal tolerance, no proximal regularisation (H is definite)
        self._model.settings = dict(primal_tol=1e-12, iter_limit=self.max_iter, eps_prox=0.0)
        flag, _ = self._model.setup(self.H, g, self.Arows, self._bu, self._bl, self._sense)
        if flag < 0:
            raise MPCFailure(FailureKind.SOLVER, f"DAQP setup failed (exit flag {flag})")

    def _raise(self, flag: int) -> None:
        if flag == _INFEASIBLE:
            raise MPCFailure(FailureKind.INFEASIBLE, "MPC problem is infeasible from the current state")
        if flag == _ITERLIMIT:
            raise MPCFailure(FailureKind.MAX_ITER, f"DAQP reached its iteration limit ({self.max_iter})")
        raise MPCFailure(FailureKind.SOLVER, f"DAQP failed (exit flag {flag})")

    def cost(self, x0: np.ndarray, U: np.ndarray) -> float:
        """``J(U; x0) = U'HU + 2 g'U + c(x0)``: the MPC cost of input sequence ``U`` from ``x0``."""
        g = self.Gx @ x0 + self.g0 + self.g_ref
        e = self.Sx @ x0 - self.rbar
        d0 = x0 - self.r
        return float(U @ self.H @ U + 2 * g @ U + e @ self.Qbar @ e + d0 @ self.Q @ d0 + self.c_ref)


def active_set_solution(
    H: np.ndarray, g: np.ndarray, upper: np.ndarray, lower: np.ndarray, ub: np.ndarray, tol: float = 1e-12
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact minimiser of a batch of box QPs for a *guessed* active set, and whether it is optimal.

    For each problem ``min 1/2 U'HU + g'U  s.t. |U| <= ub`` the variables in
    ``upper`` (``lower``) are fixed at ``+ub`` (``-ub``) and the rest solve the
    equality-constrained problem ``H_FF U_F = -(g_F + H_FA U_A)``. The guess is
    the optimum iff the KKT conditions hold: the free variables are inside the
    box and every multiplier is non-negative -- ``lambda_i = -(HU + g)_i`` at an
    upper bound, ``+(HU + g)_i`` at a lower bound. Then ``U`` equals what an
    active-set solver returns (same linear system, rounding only).

    Parameters
    ----------
    H : ndarray, shape (S, nU, nU)
        Positive definite Hessians.
    g : ndarray, shape (S, nU)
    upper, lower : ndarray of bool, shape (S, nU)
        Guessed active bounds (disjoint).
    ub : ndarray, shape (nU,)
        Box half-widths.
    tol : float
        Relative slack of the checks (rounding; a failed check only means "ask the solver").

    Returns
    -------
    U : ndarray, shape (S, nU)
    ok : ndarray of bool, shape (S,)
        True where ``U`` is the exact optimum.
    grad : ndarray, shape (S, nU)
        ``HU + g``.
    """
    S, nU = g.shape
    fixed = upper | lower
    val = np.where(upper, ub, np.where(lower, -ub, 0.0))
    # rows of fixed variables become "U_i = bound_i"; the free rows keep H (the fixed U_j enter through H_FA)
    M = np.where(fixed[:, :, None], np.eye(nU), H)
    rhs = np.where(fixed, val, -g)
    U = np.linalg.solve(M, rhs[..., None])[..., 0]
    grad = np.einsum("sij,sj->si", H, U) + g
    lam = np.where(upper, -grad, np.where(lower, grad, 0.0))
    scale = 1.0 + np.abs(g).max(axis=1, keepdims=True)
    inside = np.abs(U) <= ub * (1 + tol)
    ok = np.all(np.isfinite(U), axis=1) & np.all(inside | fixed, axis=1) & np.all(lam >= -tol * scale, axis=1)
    return U, ok, grad


def box_qp_batch(
    H: np.ndarray, g: np.ndarray, ub: np.ndarray, upper: np.ndarray, lower: np.ndarray, iters: int = 8
) -> tuple[np.ndarray, np.ndarray]:
    """Solve a batch of box QPs by primal-dual active-set iterations from a guessed active set.

    Each iteration solves every unsettled problem on its current active set
    (:func:`active_set_solution`); those passing the KKT check are done, the
    others update their set by the primal-dual active-set rule (Hintermüller,
    Ito, Kunisch 2002) with the coordinate-wise Newton step ``y = U - grad/diag(H)``:
    upper-active where ``y > ub``, lower-active where ``y < -ub``, else free.
    Problems not settled after ``iters`` iterations are left to the caller's
    solver (``ok`` False). A settled ``U`` is exact (its KKT conditions hold).

    Parameters
    ----------
    H : ndarray, shape (S, nU, nU); g : ndarray, shape (S, nU); ub : ndarray, shape (nU,)
    upper, lower : ndarray of bool, shape (S, nU)
        Initial guess of the active bounds.
    iters : int

    Returns
    -------
    U : ndarray, shape (S, nU) (NaN where not settled); ok : ndarray of bool, shape (S,)

    Notes
    -----
    With numba the compiled :func:`qsid_core.quantization.kernels.box_qp_pdas` runs (same rule
    and check, a Cholesky solve per problem); else the batched numpy version below.
    """
    from ..quantization import kernels

    if kernels.AVAILABLE:
        solved: tuple[np.ndarray, np.ndarray] = kernels.box_qp_pdas(H, g, ub, upper, lower, iters)
        return solved
    S, nU = g.shape
    U = np.full((S, nU), np.nan)
    ok = np.zeros(S, dtype=bool)
    todo = np.arange(S)
    upper, lower = upper.copy(), lower & ~upper
    for _ in range(iters):
        Hk = H[todo]
        Uk, okk, grad = active_set_solution(Hk, g[todo], upper[todo], lower[todo], ub)
        U[todo[okk]] = Uk[okk]
        ok[todo[okk]] = True
        todo, Uk, grad, Hk = todo[~okk], Uk[~okk], grad[~okk], Hk[~okk]
        if not todo.size:
            break
        y = Uk - grad / np.diagonal(Hk, axis1=1, axis2=2)
        upper[todo], lower[todo] = y > ub, y < -ub
    return U, ok
