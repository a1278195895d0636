"""Preview of a time-varying reference for the batched closed loops (:mod:`qsid_core.closed_loop`).

The MPC at step ``t`` minimises ``sum_k (x_k - r_{t+k})'Q(x_k - r_{t+k}) + u_k'R u_k``
(terminal weight on ``x_N - r_{t+N}``). In the condensed form (:mod:`qsid_core.condensed_qp`)
the reference only shifts the linear term, ``g = Gx x + Gr rbar(t)`` with
``rbar(t) = [r_{t+1}; ...; r_{t+N}]``, so the unconstrained optimum is
``U = -H^-1 (Gx x + Gr rbar(t))``: the fast path's affine law gains the offset
``-H^-1 Gr rbar(t)`` on the predicted inputs (and ``Su`` times it on the predicted
states when a state box is set). Everything stays exact.
"""

from __future__ import annotations

import numpy as np

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

    def __init__(self, cq, rows: int, reference: np.ndarray):
        self.r = np.asarray(reference, dtype=float)
        L, nU, nN = cq.Gr.shape
        self.n = self.r.shape[1]
        self.N = nN // self.n
        self.Gr = cq.Gr
        Fu = -np.linalg.solve(cq.H, cq.Gr)  # (L, N m, N n)
        self.Fr = Fu if rows == nU else np.concatenate([Fu, cq.Su @ Fu], axis=1)

    def rbar(self, t: int) -> np.ndarray:
        """``[r_{t+1}; ...; r_{t+N}]``, shape (N n,)."""
        return self.r[t + 1 : t + 1 + self.N].reshape(-1)

    def offsets(self, j: np.ndarray, t: int, H: int) -> np.ndarray:
        """Reference part of the prediction map of models ``j`` at steps ``t .. t+H-1``, shape (len(j), H, rows)."""
        R = np.stack([self.rbar(t + h) for h in range(H)])  # (H, N n)
        return np.einsum("lrk,hk->lhr", self.Fr[j], R)

    def g(self, j: np.ndarray, t: int) -> np.ndarray:
        """``Gr rbar(t)`` of models ``j``, shape (len(j), N m)."""
        return np.einsum("lqk,k->lq", self.Gr[j], self.rbar(t))

    def set_qp(self, qp, k: int, t: int) -> None:
        """Point one model's :class:`~qsid_core.condensed_qp.DaqpMPC` at the reference window of step ``t``."""
        qp.g_ref = self.Gr[k] @ self.rbar(t)
        qp.rbar, qp.r = self.rbar(t), self.r[t]
