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

import contextlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ConfigError, FailureKind, MPCFailure, check_float, check_int
from ..validate import as_float_array

__all__ = ["riccati_finite", "UltimateBound", "ultimate_bound", "RealizedBounds", "realized_bounds"]


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
) -> tuple[np.float64, np.float64, np.float64, np.float64, np.float64]:
    """``(delta, omega_v, ||dA||, ||dB||, C)`` of the proof of Theorem 3, in numpy scalars: an overflow gives inf
    (explained by the caller), never OverflowError/ZeroDivisionError."""
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        omega_v = np.float64(2.0) * pmax * rho
        na, nb = np.float64(np.linalg.norm(dA)), np.float64(np.linalg.norm(dB))
        C = omega_v**2 * (na**2 / (2 * np.float64(alpha1)) + nb**2 / (2 * np.float64(alpha2)))
        delta = np.sqrt(pmax / np.float64(pmin) * 2 * C / (np.float64(theta) * alpha1))
    return delta, omega_v, na, nb, C


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
    delta, omega_v, na, nb, C = _delta(pmin, pmax, rho, alpha1, alpha2, theta, dA, dB)
    note = ""
    if not np.isfinite(delta):
        delta = np.float64(np.inf)
        note = (
            f"no bound: delta overflows the floating-point range (rho = {rho:.3g}, lambda_max(P) = {pmax:.3g}, "
            f"theta = {theta:.3g}, alpha1 = {alpha1:.3g})"
        )
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


def _bounds_batch(
    P: NDArray[np.float64],
    Q: NDArray[np.float64],
    R: NDArray[np.float64],
    dA: NDArray[np.float64],
    dB: NDArray[np.float64],
    theta: float,
    rho: float | None,
    x0: ArrayLike | None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """:func:`ultimate_bound`'s ``delta`` and ``rho`` for a batch (P (L, n, n), dA (L, n, n), dB (L, n, m)).

    The same formulas, evaluated for all models at once; returns ``(delta, rho, odd)``
    where ``odd`` marks the models whose automatic ``rho`` is not a finite positive
    number (left to :func:`ultimate_bound`, which raises the same error as one at a time).
    """
    theta = check_float("theta", theta, 0.0, 1.0, lo_open=True, hi_open=True)
    alpha1, alpha2 = float(np.linalg.eigvalsh(Q).min()), float(np.linalg.eigvalsh(R).min())
    if alpha1 <= 0 or alpha2 <= 0:
        raise ConfigError("the ultimate bound needs Q and R positive definite (letter, Assumption 4)")
    L = P.shape[0]
    Ps = (P + np.swapaxes(P, 1, 2)) / 2
    with np.errstate(all="ignore"):
        ep = np.linalg.eigvalsh(np.where(np.isfinite(Ps), Ps, 0.0))
        pmin, pmax = ep[:, 0], ep[:, -1]
        pd = (pmin > 0) & np.all(np.isfinite(Ps.reshape(L, -1)), axis=1)
        if rho is not None:
            r = np.full(L, check_float("rho", rho, 0.0, lo_open=True))
        elif x0 is not None and np.linalg.norm(x0) > 0:
            x0v = np.asarray(x0, dtype=float)
            r = np.sqrt(np.maximum(np.einsum("i,lij,j->l", x0v, Ps, x0v), 0.0) / pmin)
        else:
            r = np.sqrt(pmax / pmin)
        odd = pd & ~(np.isfinite(r) & (r > 0))
        omega = 2.0 * pmax * r
        na = np.linalg.norm(dA.reshape(L, -1), axis=1)
        nb = np.linalg.norm(dB.reshape(L, -1), axis=1)
        C = omega**2 * (na**2 / (2 * alpha1) + nb**2 / (2 * alpha2))
        delta = np.sqrt(pmax / pmin * 2 * C / (theta * alpha1))
    delta = np.where(np.isfinite(delta), delta, np.inf)
    return np.where(pd, delta, np.inf), np.where(pd, r, np.nan), odd


def _riccati_finite_batch(
    A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, Qf: np.ndarray, horizon: int
) -> np.ndarray:
    """:func:`riccati_finite` for a batch: A (L, n, n), B (L, n, m), Qf (L, n, n) -> P_0 (L, n, n).

    A problem whose ``R + B'PB`` becomes singular (input weights negligible against a model with a
    zero input direction) gets a NaN ``P_0``: it has no bound; the others are unaffected.
    """
    P = np.array(Qf, dtype=float)
    At = np.swapaxes(A, 1, 2)
    Bt = np.swapaxes(B, 1, 2)
    for _ in range(horizon):
        BtP = Bt @ P
        BtPA = BtP @ A
        P = At @ P @ A - np.swapaxes(BtPA, 1, 2) @ _solve_each(R + BtP @ B, BtPA) + Q
        P = (P + np.swapaxes(P, 1, 2)) / 2
    return P


def _solve_each(M: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """``M^-1 Y`` for a batch (L, m, m), (L, m, k); NaN for the problems whose ``M`` is singular."""
    try:
        return np.asarray(np.linalg.solve(M, Y))
    except np.linalg.LinAlgError:
        out = np.full(Y.shape, np.nan)
        for i in range(M.shape[0]):
            with contextlib.suppress(np.linalg.LinAlgError):
                out[i] = np.linalg.solve(M[i], Y[i])
        return out


def _weights(Q: ArrayLike, R: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``Q`` symmetric positive semidefinite and ``R`` symmetric positive definite, as float arrays."""
    Qa, Ra = as_float_array("Q", Q, max_abs=None), as_float_array("R", R, max_abs=None)
    for name, W, strict in (("Q", Qa, False), ("R", Ra, True)):
        if W.ndim != 2 or W.shape[0] != W.shape[1] or not np.allclose(W, W.T):
            raise ConfigError(f"{name} must be a symmetric square matrix; got shape {W.shape}")
        low = float(np.linalg.eigvalsh(W).min())
        if low < 0 or (strict and low <= 0):
            need = "positive definite" if strict else "positive semidefinite"
            raise ConfigError(f"{name} must be {need}; its smallest eigenvalue is {low:g}")
    return Qa, Ra


@dataclass
class RealizedBounds:
    """A-posteriori ultimate bounds, one per realization (see :func:`realized_bounds`).

    Attributes
    ----------
    delta : ndarray, shape (R,)
        Bound of each realization (state units); ``inf`` where its ``P`` is not
        positive definite or no terminal weight exists, ``nan`` for a failed
        identification.
    rho : ndarray, shape (R,)
        The ``rho`` each bound used (automatic unless configured).
    """

    delta: np.ndarray
    rho: np.ndarray
    x0_norm: float = float("nan")

    @property
    def self_consistent(self) -> int:
        """Realizations whose bound is below its ``rho`` (elsewhere the proof gives no bound)."""
        with np.errstate(invalid="ignore"):
            return int(np.sum(np.asarray(self.delta, float) < np.asarray(self.rho, float)))

    @property
    def informative(self) -> int:
        """Realizations whose bound is below ``||x0||``."""
        with np.errstate(invalid="ignore"):
            return int(np.sum(np.asarray(self.delta, float) < self.x0_norm))

    def _finite(self) -> np.ndarray:
        d = np.asarray(self.delta, dtype=float)
        finite: np.ndarray = d[np.isfinite(d)]
        return finite

    @property
    def median(self) -> float:
        """Median over realizations with a finite bound (NaN if none)."""
        f = self._finite()
        return float(np.median(f)) if f.size else float("nan")

    @property
    def max(self) -> float:
        """Largest bound; ``inf`` if any realization has none (NaN if all identifications failed)."""
        d = np.asarray(self.delta, dtype=float)
        d = d[~np.isnan(d)]
        return float(d.max()) if d.size else float("nan")

    @property
    def unbounded(self) -> int:
        """Realizations whose bound is infinite (no positive definite P)."""
        return int(np.isinf(np.asarray(self.delta, dtype=float)).sum())


def realized_bounds(
    models: Sequence[tuple[np.ndarray, np.ndarray]],
    A: np.ndarray,
    B: np.ndarray,
    Q: np.ndarray,
    R: np.ndarray,
    Qf: np.ndarray | None,
    horizon: int,
    *,
    theta: float = 0.5,
    rho: float | None = None,
    x0: np.ndarray | None = None,
) -> RealizedBounds:
    """A-posteriori ultimate bound of each realization: its own model error and its own ``P``.

    Parameters
    ----------
    models : sequence of (A^, B^), shapes (n, n) and (n, m)
        Identified models (NaN entries mark failed identifications).
    A, B : ndarray
        The true system.
    Q, R : ndarray, shapes (n, n), (m, m)
        MPC weights.
    Qf : ndarray or None
        Terminal weight; None uses each model's stabilizing DARE solution.
    horizon : int
        MPC horizon (steps of the Riccati recursion).
    theta, rho, x0
        As in :func:`ultimate_bound` (``rho=None``: automatic per realization).
    """
    from ..errors import MPCFailure
    from .riccati import dare_batch, dare_stabilizing

    Q, R = _weights(Q, R)
    Rn = len(models)
    delta = np.full(Rn, np.nan)
    rhos = np.full(Rn, np.nan)
    ok = [i for i, (a, b) in enumerate(models) if np.all(np.isfinite(a)) and np.all(np.isfinite(b))]
    Qfs: dict[int, np.ndarray | None] = {i: Qf for i in ok}
    if Qf is None and ok:
        X, good = dare_batch(np.stack([models[i][0] for i in ok]), np.stack([models[i][1] for i in ok]), Q, R)
        for k, i in enumerate(ok):
            if good[k]:
                Qfs[i] = X[k]
            else:
                try:
                    Qfs[i] = dare_stabilizing(models[i][0], models[i][1], Q, R)
                except MPCFailure:
                    Qfs[i] = None
    settled = {i: qf for i, qf in Qfs.items() if qf is not None}
    todo = list(settled)
    delta[[i for i in ok if i not in settled]] = np.inf
    if todo:
        P = _riccati_finite_batch(
            np.stack([models[i][0] for i in todo]),
            np.stack([models[i][1] for i in todo]),
            Q,
            R,
            np.stack([settled[i] for i in todo]),
            horizon,
        )
        finite = np.all(np.isfinite(P), axis=(1, 2))  # a singular recursion: no bound for that model
        delta[[i for i, f in zip(todo, finite) if not f]] = np.inf
        todo = [i for i, f in zip(todo, finite) if f]
        P = P[finite]
    if todo:
        dA = A - np.stack([models[i][0] for i in todo])
        dB = B - np.stack([models[i][1] for i in todo])
        d, r, odd = _bounds_batch(P, Q, R, dA, dB, theta, rho, x0)
        for k in np.flatnonzero(odd).tolist():  # an automatic rho that is no positive number: ultimate_bound says why
            ub = ultimate_bound(P[k], Q, R, dA[k], dB[k], theta=theta, rho=rho, x0=x0)
            d[k], r[k] = ub.delta, ub.rho
        delta[todo], rhos[todo] = d, r
    return RealizedBounds(delta, rhos, float(np.linalg.norm(x0)) if x0 is not None else float("nan"))
