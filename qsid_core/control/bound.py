"""The letter's ultimate bound of the MPC on an identified model (Theorem 3), and its a-posteriori companion.

Theorem 1 (large-data regime), per-channel form::

    G_pred = [A, B] Sigma (Sigma + D)^-1,   Sigma = Psi_uqz Psi_uqz^T / T,
    D = diag(eps_i**2 / 12)

With one shared eps, ``D = eps**2/12 I`` and this is exactly the letter's
``[A, B] - eps**2 [A, B] (12 Sigma + eps**2 I)^-1`` (Theorem 1, eq. (5)).

Equation numbers follow the letter (../shared/paper/qsid-mpc-letter.tex): (1) dynamics,
(2) MPC problem, (3)-(4) least squares and data matrices, (5) Theorem 1, (6)-(7)
Theorem 2 and the LS closed form, (8)-(11) the Lyapunov steps of the proof of
Theorem 3 (uniform ultimate boundedness).

Ultimate bound (proof of Theorem 3, eqs. (8)-(11)): with ``V(x) = x^T P x``,
``P`` from the finite-horizon Riccati recursion of ``(A^, B^, Q, R)`` with
``P_Th = Qf``; ``alpha1 = lambda_min(Q)``, ``alpha2 = lambda_min(R)``;
``omega_v = 2 lambda_max(P) rho`` (Lipschitz constant of ``x^T P x`` on the
ball of radius ``rho``); ``C = omega_v**2 (||dA||**2/(2 alpha1) + ||dB||**2/(2 alpha2))``
with ``dA = eps^2 Delta_A``, ``dB = eps^2 Delta_B`` the model errors predicted
by Theorem 1; ``delta = sqrt(lambda_max(P)/lambda_min(P) * 2C/(theta alpha1))``.

Two bounds are computed, with the same formula and different ingredients:

* the **letter's** ``delta(eps)`` (:meth:`Experiment.theory`): model errors
  ``c_A = ||A - A_pred||_F``, ``c_B = ||B - B_pred||_F`` of Theorem 1's
  large-data (T -> inf) prediction, ``P`` from the predicted model;
* the **a-posteriori** bound (:func:`realized_bounds`): for each realization its
  own actual model error ``||A - A^_r||_F``, ``||B - B^_r||_F`` and its own ``P_r``
  (the model the MPC actually runs on). Finite-data models have O(eps) errors, so
  this bound is O(eps), not O(eps^2); it is the honest companion of the letter's.

Both bound ``||x_t||`` only as t -> inf, and assume ``x_ref = 0``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ConfigError, FailureKind, MPCFailure, check_float, check_int
from ..validate import as_float_array

__all__ = ["riccati_finite", "UltimateBound", "ultimate_bound"]


def riccati_finite(
    A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, Qf: np.ndarray, horizon: int
) -> np.ndarray:
    """``P_0`` of ``P_{k-1} = A'P_kA - A'P_kB(R + B'P_kB)^-1 B'P_kA + Q``, ``P_Th = Qf`` (letter, proof of Thm. 3).

    Parameters
    ----------
    A : ndarray, shape (n, n); B : ndarray, shape (n, m)
    Q, Qf : ndarray, shape (n, n); R : ndarray, shape (m, m)
    horizon : int, >= 0

    Raises
    ------
    ConfigError
        Non-finite or mis-shaped matrices, a negative horizon.
    MPCFailure
        ``R + B'PB`` is singular at some step (input weights negligible against an input the model says
        moves nothing), or the recursion overflows: there is no bound for this model.
    """
    A, B = as_float_array("A", A, max_abs=None), as_float_array("B", B, max_abs=None)
    Q, R = as_float_array("Q", Q, max_abs=None), as_float_array("R", R, max_abs=None)
    P = np.array(as_float_array("Qf", Qf, max_abs=None), dtype=float)
    horizon = check_int("horizon", horizon, 0)
    n, m = B.shape if B.ndim == 2 else (0, 0)
    if A.shape != (n, n) or Q.shape != (n, n) or P.shape != (n, n) or R.shape != (m, m):
        raise ConfigError(f"riccati_finite needs A, Q, Qf (n, n), B (n, m), R (m, m); got B {B.shape}")
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(horizon):
            BtP = B.T @ P
            try:
                P = A.T @ P @ A - (BtP @ A).T @ np.linalg.solve(R + BtP @ B, BtP @ A) + Q
            except np.linalg.LinAlgError:
                raise MPCFailure(
                    FailureKind.SOLVER, "no bound: R + B'PB is singular in the Riccati recursion"
                ) from None
            P = (P + P.T) / 2
    if not np.all(np.isfinite(P)):
        raise MPCFailure(FailureKind.SOLVER, "no bound: the Riccati recursion overflows the floating-point range")
    return P


@dataclass
class UltimateBound:
    """The ultimate bound and its ingredients (letter, proof of Theorem 3, eqs. (8)-(11))."""

    delta: float
    P_eig_min: float
    P_eig_max: float
    alpha1: float
    alpha2: float
    omega_v: float
    rho: float
    theta: float
    dA_norm: float
    dB_norm: float
    C: float
    note: str = ""  #: why ``delta`` is infinite, in plain words (empty when it is finite)
    x0_norm: float = float("nan")  #: ``||x0||`` of the loop it bounds (NaN if not given)

    @property
    def self_consistent(self) -> bool:
        """``delta < rho``: the proof assumes the state stays in the ball of radius ``rho``; an
        ultimate bound at least ``rho`` contradicts that assumption, so the proof gives no bound."""
        return bool(self.delta < self.rho)

    @property
    def informative(self) -> bool:
        """``delta < ||x0||``: the bound says more than "the state ends no farther out than it started"."""
        return bool(self.delta < self.x0_norm)


def _auto_rho(P: np.ndarray, pmin: float, pmax: float, x0: ArrayLike | None) -> float:
    """The default ``rho``: radius of the smallest ball holding ``{x'Px <= x0'P x0}`` (worst unit x0 without x0)."""
    if x0 is not None and np.linalg.norm(x0) > 0:
        x0v = np.asarray(x0, dtype=float)
        return float(np.sqrt(max(x0v @ ((P + P.T) / 2) @ x0v, 0.0) / pmin))
    return float(np.sqrt(pmax / pmin))


def _delta(
    pmin: float, pmax: float, rho: float, alpha1: float, alpha2: float, theta: float, dA: np.ndarray, dB: np.ndarray
) -> tuple[np.float64, np.float64, np.float64, np.float64, np.float64, str]:
    """``(delta, omega_v, ||dA||, ||dB||, C, note)`` of the proof of Theorem 3, in numpy scalars: an overflow
    gives ``delta = inf`` and says so in the note, never OverflowError/ZeroDivisionError."""
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        omega_v = np.float64(2.0) * pmax * rho
        na, nb = np.float64(np.linalg.norm(dA)), np.float64(np.linalg.norm(dB))
        C = omega_v**2 * (na**2 / (2 * np.float64(alpha1)) + nb**2 / (2 * np.float64(alpha2)))
        delta = np.sqrt(pmax / np.float64(pmin) * 2 * C / (np.float64(theta) * alpha1))
    if np.isfinite(delta):
        return delta, omega_v, na, nb, C, ""
    note = (
        f"no bound: delta overflows the floating-point range (rho = {rho:.3g}, lambda_max(P) = {pmax:.3g}, "
        f"theta = {theta:.3g}, alpha1 = {alpha1:.3g})"
    )
    return np.float64(np.inf), omega_v, na, nb, C, note


def _no_lyapunov(
    pmin: float,
    pmax: float,
    alpha1: float,
    alpha2: float,
    theta: float,
    dA: np.ndarray,
    dB: np.ndarray,
    x0_norm: float,
) -> UltimateBound:
    """No bound: ``P`` is not positive definite, so ``V(x) = x'Px`` is no Lyapunov function."""
    return UltimateBound(
        float("inf"),
        pmin,
        pmax,
        alpha1,
        alpha2,
        float("inf"),
        float("nan"),
        theta,
        float(np.linalg.norm(dA)),
        float(np.linalg.norm(dB)),
        float("inf"),
        note=f"no bound: the Riccati matrix P is not positive definite "
        f"(lambda_min(P) = {pmin:.3g}), so V(x) = x'Px is no Lyapunov function",
        x0_norm=x0_norm,
    )


def ultimate_bound(
    P: np.ndarray,
    Q: np.ndarray,
    R: np.ndarray,
    dA: np.ndarray,
    dB: np.ndarray,
    *,
    theta: float = 0.5,
    rho: float | None = None,
    x0: np.ndarray | None = None,
) -> UltimateBound:
    """Ultimate bound ``delta(eps)`` of the closed loop (letter, Theorem 3 and its proof).

    Modelling choices (the letter leaves these open; each is made here explicitly):

    * ``V(x) = x' P x`` with ``P = P_0`` of the finite-horizon Riccati recursion of
      the *identified* model ``(A^, B^, Q, R)`` over the MPC horizon, ``P_Th = Qf``;
      ``Qf`` is the configured terminal weight or, by default, the stabilizing DARE
      solution of ``(A^, B^, Q, R)`` (then ``P = Qf``). Which model: Theorem 1's
      prediction for the letter's bound, each realization's own model for the
      a-posteriori bound (:func:`realized_bounds`).
    * ``alpha1 = lambda_min(Q)``, ``alpha2 = lambda_min(R)`` (Assumption 4).
    * ``omega_v = 2 lambda_max(P) rho``: Lipschitz constant of ``V`` on the ball of
      radius ``rho``; ``rho`` automatic (below) unless given; the value used is
      returned in :attr:`UltimateBound.rho`.
    * ``c_A = ||dA||_F``, ``c_B = ||dB||_F`` (Frobenius), with ``eps^2`` absorbed: ``dA = eps^2 Delta_A``.
    * ``theta`` in (0, 1), default 0.5.
    * The bound holds only as t -> inf and for ``x_ref = 0``; input and state
      constraints are not part of the proof's quadratic ``V``.

    Parameters
    ----------
    P : ndarray, shape (n, n)
        Riccati matrix of the MPC value function ``V(x) = x' P x`` (see :func:`riccati_finite`).
    Q, R : ndarray
        MPC weights; ``alpha1 = lambda_min(Q)`` must be > 0 (Assumption 4).
    dA, dB : ndarray
        Model errors ``A - A^``, ``B - B^`` (the Theorem 1 prediction in the sweep).
    theta : float in (0, 1)
        Share of the decrease used to dominate the disturbance (default 0.5).
    rho : float > 0, optional
        Radius of the ball the state stays in, for ``omega_v = 2 lambda_max(P) rho``.
        Default: ``sqrt(x0'P x0 / lambda_min(P))``, the radius of the smallest ball
        holding ``{V <= V(x0)}``; without ``x0``: ``sqrt(lambda_max(P)/lambda_min(P))``.

    Raises
    ------
    ConfigError
        If theta is not in (0, 1), rho <= 0, or Q / R are not positive definite.
    """
    theta = check_float("theta", theta, 0.0, 1.0, lo_open=True, hi_open=True)
    alpha1, alpha2 = float(np.linalg.eigvalsh(Q).min()), float(np.linalg.eigvalsh(R).min())
    if alpha1 <= 0 or alpha2 <= 0:
        raise ConfigError("the ultimate bound needs Q and R positive definite (letter, Assumption 4)")
    ep = np.linalg.eigvalsh((P + P.T) / 2)
    pmin, pmax = float(ep.min()), float(ep.max())
    x0_norm = float(np.linalg.norm(x0)) if x0 is not None else float("nan")
    if not (pmin > 0 and np.isfinite(pmax)):
        return _no_lyapunov(pmin, pmax, alpha1, alpha2, theta, dA, dB, x0_norm)
    rho = check_float("rho", _auto_rho(P, pmin, pmax, x0) if rho is None else rho, 0.0, lo_open=True)
    delta, omega_v, na, nb, C, note = _delta(pmin, pmax, rho, alpha1, alpha2, theta, dA, dB)
    return UltimateBound(
        float(delta),
        pmin,
        pmax,
        alpha1,
        alpha2,
        float(omega_v),
        float(rho),
        theta,
        float(na),
        float(nb),
        float(C),
        note=note,
        x0_norm=x0_norm,
    )
