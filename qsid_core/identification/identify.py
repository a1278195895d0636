"""Least-squares identification of [A, B] and its bias-compensated variant.

Least squares (letter, eq. (3); closed form eq. (7) in the proof of Theorem 2)::

    G = [A^, B^] = X+ Psi^T (Psi Psi^T)^-1

Bias-compensated least squares (BCLS): Theorem 1 shows the LS bias comes from
``E[Psi~ Psi~^T] = Psi Psi^T + T D`` with ``D = diag(eps_i**2 / 12)``, which the
subtractive dither makes *known*. BCLS uses ``Psi~ Psi~^T - T D`` in place of
``Psi~ Psi~^T``. Non-subtractive triangular (TPDF) dither also gives a known,
signal-independent error variance, ``eps**2 / 4`` (see :mod:`qsid_core.quantization.quantize`);
:attr:`Moments.D <qsid_core.quantization.moments.Moments>` carries the ``D`` of the dither used, and
:attr:`Moments.bcls_note` says when none is known (RPDF dither, no dither): BCLS then
uses a nominal ``eps**2 / 12`` and its note says it does not apply. The noise of ``X~+`` is independent of that of ``Psi~`` (other
samples, other dither draws), so ``X~+ Psi~^T`` needs no correction. When the
corrected matrix is not positive definite (quantization noise comparable to the
signal) BCLS is meaningless; :func:`identify` then falls back to plain LS and
says so in :attr:`Identified.note`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ..errors import IdentificationError, check_choice
from ..quantization.moments import Moments

__all__ = ["ESTIMATORS", "Identified", "identify", "least_squares", "mean_std_of_known", "relative_errors"]

ESTIMATORS = ("ls", "bcls")
#: An identified entry beyond this is a numerical failure (true systems have entries <= 1e12).
MAX_MODEL_MAGNITUDE = 1e150


@dataclass
class Identified:
    """An identified model.

    Attributes
    ----------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, m)
    estimator : str
        The estimator actually used (``"ls"`` after a BCLS fallback).
    fallback : bool
        True if BCLS was asked for but its corrected Gram matrix was not
        positive definite, so LS was used.
    note : str
        Plain-words explanation of a fallback (empty otherwise).
    """

    A: np.ndarray
    B: np.ndarray
    estimator: str
    fallback: bool = False
    note: str = ""

    @property
    def G(self) -> np.ndarray:
        return np.hstack([self.A, self.B])


def _solve_spd(PP: np.ndarray, XP: np.ndarray) -> np.ndarray | None:
    """``XP PP^-1`` via Cholesky with diagonal scaling; None if PP is not positive definite."""
    d = np.sqrt(np.clip(np.diag(PP), 1e-300, None))
    with np.errstate(over="ignore", invalid="ignore"):  # a scale this far apart is refused just below
        S = PP / np.outer(d, d)
    if not np.all(np.isfinite(S)):
        return None
    try:
        c = sla.cho_factor(S, lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        return None
    if np.min(np.abs(np.diag(c[0]))) < 1e-7:
        return None
    G: np.ndarray = sla.cho_solve(c, (XP / d[None, :]).T, check_finite=False).T / d[None, :]
    return G


def least_squares(PP: np.ndarray, XP: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``[A^, B^] = XP PP^-1`` split into ``(A^, B^)``.

    Raises
    ------
    IdentificationError (a ValueError)
        If ``PP`` is singular (data not rich enough: Psi must have full row rank)
        or the solution is not finite.
    """
    G = _solve_spd(PP, XP)
    if G is None:
        raise IdentificationError("Psi Psi^T is singular: the data are not rich enough to identify A and B")
    if not np.all(np.abs(G) <= MAX_MODEL_MAGNITUDE):  # also catches nan/inf
        raise IdentificationError(
            "least squares gave entries beyond 1e150 or non-finite numbers (Psi Psi^T is "
            "too badly conditioned): no model"
        )
    return G[:, :n], G[:, n:]


def _check_moments(mom: Moments) -> Moments:
    """``mom`` with float arrays, after checking shapes and types of ``mom`` (PP p x p, XP n x p with n < p, eps p numbers, T >= 1), else the engine's error."""
    try:
        PP, XP, eps = (np.asarray(v, dtype=float) for v in (mom.PP, mom.XP, mom.eps))
    except (TypeError, ValueError):
        raise IdentificationError("the moments must hold real numbers (PP, XP, eps)") from None
    if PP.ndim != 2 or PP.shape[0] != PP.shape[1] or PP.shape[0] == 0:
        raise IdentificationError(f"moments PP must be a non-empty square matrix; got shape {PP.shape}")
    p = PP.shape[0]
    if XP.ndim != 2 or XP.shape[1] != p or not 0 < XP.shape[0] < p:
        raise IdentificationError(f"moments XP must be n x {p} with 0 < n < {p}; got shape {XP.shape}")
    if eps.shape != (p,):
        raise IdentificationError(f"moments eps must have {p} entries (one per regressor); got shape {eps.shape}")
    if isinstance(mom.T, bool) or not isinstance(mom.T, (int, np.integer)) or mom.T < 1:
        raise IdentificationError(f"moments T must be a positive integer; got {mom.T!r}")
    return dataclasses.replace(mom, PP=PP, XP=XP, eps=eps)


def identify(mom: Moments, estimator: str = "ls") -> Identified:
    """Identify ``(A^, B^)`` from Gram matrices of (quantized) data.

    Parameters
    ----------
    mom : Moments
        ``PP = Psi Psi^T`` (p x p), ``XP = X+ Psi^T`` (n x p), ``T`` and ``eps``.
    estimator : {"ls", "bcls"}
        Plain least squares or bias-compensated least squares.
    """
    check_choice("estimator", estimator, ESTIMATORS)
    mom = _check_moments(mom)
    if not all(np.all(np.isfinite(v)) for v in (mom.PP, mom.XP, mom.eps)):
        raise IdentificationError("the quantized data are not finite numbers (check the quantizer range): no model")
    n = mom.XP.shape[0]
    if estimator == "bcls":
        D = mom.T * mom.noise_variance
        not_applicable = (
            f"BCLS not applicable: {mom.bcls_note}; a nominal D = eps^2/12 was used" if mom.bcls_note else ""
        )
        G = _solve_spd(mom.PP - np.diag(D), mom.XP)
        if G is not None and np.all(np.abs(G) <= MAX_MODEL_MAGNITUDE):
            return Identified(G[:, :n], G[:, n:], "bcls", note=not_applicable)
        A, B = least_squares(mom.PP, mom.XP, n)
        return Identified(
            A,
            B,
            "ls",
            fallback=True,
            note="bias compensation impossible: Psi Psi^T - T*D is not positive definite "
            "(quantization noise comparable to the signal); plain LS used",
        )
    A, B = least_squares(mom.PP, mom.XP, n)
    return Identified(A, B, "ls")


def mean_std_of_known(x: np.ndarray) -> tuple[float, float]:
    """Mean and std of the values of ``x`` that are not NaN (failed identifications); NaN for both, without
    numpy's warning, when every one failed. (:class:`qsid_core.studies.summary.Stats` also
    leaves infinities out and gives None.)"""
    x = np.asarray(x, dtype=float)
    known = x[~np.isnan(x)]
    return (float(known.mean()), float(known.std())) if known.size else (float("nan"), float("nan"))


def relative_errors(A_hat: np.ndarray, B_hat: np.ndarray, A: np.ndarray, B: np.ndarray) -> tuple[float, float]:
    """``(||A - A^||_F / ||A||_F, ||B - B^||_F / ||B||_F)``.

    A true matrix that is all zeros has no size of its own to compare with: its
    error is then taken relative to the whole model, ``||[A, B]||_F`` (finite,
    since :class:`~qsid_core.plant.systems.LTISystem` rejects A = B = 0). NaN models
    (failed identifications) give NaN.
    """
    nG = float(np.linalg.norm(np.hstack([A, B])))
    nA, nB = float(np.linalg.norm(A)), float(np.linalg.norm(B))
    return (
        float(np.linalg.norm(A - A_hat) / (nA if nA > 0 else nG)),
        float(np.linalg.norm(B - B_hat) / (nB if nB > 0 else nG)),
    )
