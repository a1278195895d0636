"""Preview of a time-varying reference for the batched closed loops (:mod:`qsid_core.control.closed_loop`).

The MPC at step ``t`` minimises ``sum_k (x_k - r_{t+k})'Q(x_k - r_{t+k}) + u_k'R u_k``
(terminal weight on ``x_N - r_{t+N}``). In the condensed form (:mod:`qsid_core.control.condensed_qp`)
the reference only shifts the linear term, ``g = Gx x + Gr rbar(t)`` with
``rbar(t) = [r_{t+1}; ...; r_{t+N}]``, so the unconstrained optimum is
``U = -H^-1 (Gx x + Gr rbar(t))``: the fast path's affine law gains the offset
``-H^-1 Gr rbar(t)`` on the predicted inputs (and ``Su`` times it on the predicted
states when a state box is set). The offset-free form adds the input target:
``(u_k - u_ref,k)'R(u_k - u_ref,k)`` with ``u_ref,k = B^+ (I - A^) r_{t+k}`` adds
``-R u_ref,k`` to the rows of ``u_k``. Everything stays exact.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .condensed_qp import CondensedQP, DaqpMPC

__all__ = ["Preview"]


class Preview:
    """The reference offsets of every live model of a batch.

    Parameters
    ----------
    cq : CondensedQP
        The condensed problems of the live models (built with a zero reference).
    rows : int
        Rows of the fast path's prediction map (``N m`` inputs, plus ``N n`` states with a state box).
    reference : ndarray, shape (T, n)
        ``r_0 .. r_{T-1}`` with ``T >= steps + N + 1``.
    """

    def __init__(
        self,
        cq: CondensedQP,
        rows: int,
        reference: np.ndarray,
        offset_free: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    ) -> None:
        if cq.Gr is None:
            raise ValueError("a reference preview needs the condensed problem's reference map Gr")
        self.r = np.asarray(reference, dtype=float)
        L, nU, nN = cq.Gr.shape
        self.n = self.r.shape[1]
        self.N = nN // self.n
        # one window w(t) = [r_t; ...; r_{t+N}] drives g: r_{t+1..t+N} through Gr (state cost), and in the
        # offset-free form r_{t..t+N-1} through -R u_ref with u_ref = Ku r (input cost)
        G = np.concatenate([np.zeros((L, nU, self.n)), cq.Gr], axis=2)  # (L, N m, (N+1) n)
        self.Ku, self.R = None, None
        if offset_free is not None:
            A_hat, B_hat, R = offset_free
            m = B_hat.shape[2]
            self.Ku = np.linalg.pinv(B_hat) @ (np.eye(self.n) - A_hat)  # (L, m, n)
            self.R = np.asarray(R, dtype=float)
            RK = self.R @ self.Ku
            for k in range(self.N):
                G[:, k * m : (k + 1) * m, k * self.n : (k + 1) * self.n] -= RK
        self.G = G
        Fu = -np.linalg.solve(cq.H, G)  # (L, N m, (N+1) n)
        self.Fr = Fu if rows == nU else np.concatenate([Fu, cq.Su @ Fu], axis=1)

    def window(self, t: int) -> np.ndarray:
        """``[r_t; ...; r_{t+N}]``, shape ((N+1) n,)."""
        return self.r[t : t + 1 + self.N].reshape(-1)

    def offsets(self, j: np.ndarray, t: int, H: int) -> np.ndarray:
        """Reference part of the prediction map of models ``j`` at steps ``t .. t+H-1``, shape (len(j), H, rows)."""
        W = np.stack([self.window(t + h) for h in range(H)])  # (H, (N+1) n)
        out: np.ndarray = np.einsum("lrk,hk->lhr", self.Fr[j], W)
        return out

    def g(self, j: np.ndarray, t: int) -> np.ndarray:
        """The reference part of ``g`` of models ``j``, shape (len(j), N m)."""
        out: np.ndarray = np.einsum("lqk,k->lq", self.G[j], self.window(t))
        return out

    def set_qp(self, qp: DaqpMPC, k: int, t: int) -> None:
        """Point one model's :class:`~qsid_core.control.condensed_qp.DaqpMPC` at the reference window of step ``t``."""
        w = self.window(t)
        qp.g_ref = self.G[k] @ w
        qp.rbar, qp.r = w[self.n :], w[: self.n]
        if self.Ku is not None and self.R is not None:  # the constant of (u - u_ref)'R(u - u_ref)
            ub = self.r[t : t + self.N] @ self.Ku[k].T
            qp.c_ref = float(np.einsum("ki,ij,kj->", ub, self.R, ub))
