"""The a-posteriori ultimate bound: the letter's bound (:func:`~qsid_core.control.bound.ultimate_bound`) for
each realization's own model error and its own Riccati matrix, all models at once (:func:`realized_bounds`,
:class:`RealizedBounds`)."""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ConfigError, check_float
from ..validate import as_float_array
from .bound import ultimate_bound

__all__ = ["RealizedBounds", "realized_bounds"]


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
    from .riccati import dare_many

    Q, R = _weights(Q, R)
    Rn = len(models)
    delta = np.full(Rn, np.nan)
    rhos = np.full(Rn, np.nan)
    ok = [i for i, (a, b) in enumerate(models) if np.all(np.isfinite(a)) and np.all(np.isfinite(b))]
    Qfs: dict[int, np.ndarray | None] = {i: Qf for i in ok}
    if Qf is None and ok:
        X, good = dare_many(np.stack([models[i][0] for i in ok]), np.stack([models[i][1] for i in ok]), Q, R)
        for k, i in enumerate(ok):
            Qfs[i] = X[k] if good[k] else None
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
