"""The MPC settings resolved for one system: weights, bounds, start and reference as arrays."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MPCWeights"]


@dataclass(frozen=True, eq=False)
class MPCWeights:
    """An :class:`MPCConfig` resolved for one system (``n`` states, ``m`` inputs).

    Units are the system's: states and inputs as in ``A``, ``B``; the cost is the
    sum of ``x'Qx + u'Ru`` terms.

    Attributes
    ----------
    Q : ndarray, shape (n, n)
        Stage state weight (positive semidefinite).
    R : ndarray, shape (m, m)
        Stage input weight (positive definite).
    Qf : ndarray, shape (n, n), or None
        Terminal weight; None means "the DARE solution of each identified model".
    x0 : ndarray, shape (n,)
        Initial state of every closed loop.
    x_ref : ndarray, shape (n,)
        Constant reference the state is steered to.
    u_max : ndarray, shape (m,)
        Input box half-widths, ``|u_i| <= u_max_i`` (> 0).
    x_max : ndarray, shape (n,), or None
        State box on the predicted ``x_1..x_N``.
    xf_max : ndarray, shape (n,), or None
        Terminal box on ``x_N``.
    reference : ndarray, shape (steps + horizon + 1, n), or None
        The time-varying reference ``r_0 ..`` (with it ``x_ref`` is 0 and unused).
    """

    Q: np.ndarray
    R: np.ndarray
    Qf: np.ndarray | None
    x0: np.ndarray
    x_ref: np.ndarray
    u_max: np.ndarray
    x_max: np.ndarray | None
    xf_max: np.ndarray | None
    reference: np.ndarray | None = None
