"""What the quantizer clipping the data does to least squares: the limits it keeps, whether it clips at all
(judged from the data's extremes, without clipped copies) and the predicted change of ``[A^, B^]``
(:func:`clipping_effect`, which :mod:`~qsid_core.studies.assumptions` compares with the finite-data
fluctuation)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["clipping_effect", "clips_nothing"]


def clipping_effect(
    G: np.ndarray,
    Psi: np.ndarray,
    Xp: np.ndarray,
    lo_q: np.ndarray,
    eps: np.ndarray,
    bits: ArrayLike,
    variance: float = 1.0 / 12.0,
    extremes: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None,
    grams: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Predicted absolute change of ``[A^, B^]`` caused by the quantizer clipping the data.

    Parameters
    ----------
    G : ndarray, shape (n, n+m)
        True ``[A, B]``.
    Psi, Xp : ndarray, shapes (n+m, T) and (n, T)
        Unquantized regressors and next states.
    lo_q, eps : ndarray, shape (n+m,)
        The quantizer's lower edge and cell width per channel (:func:`~qsid_core.quantization.quantize.effective_ranges`);
        a channel recorded exactly has ``eps = 0`` and is never clipped.
    bits : int or ndarray, shape (n+m,)
        Word length (per channel).
    variance : float
        The dither's error variance in units of ``eps**2`` (1/12 subtractive, 1/4 tpdf).
    extremes : tuple of ndarray, optional
        ``(Psi_min, Psi_max, Xp_min, Xp_max)`` per channel if known
        (:meth:`~qsid_core.plant.data.Dataset.extremes`); otherwise computed from ``Psi`` and ``Xp``.
    grams : tuple of ndarray, optional
        ``(Psi Psi^T, Xp Psi^T)``, shapes (n+m, n+m) and (n, n+m), if known (the prepared data's exact
        moments); otherwise computed.

    Returns
    -------
    ndarray, shape (n, n+m)
        Entry-wise the larger of the shift of Theorem 1's LS limit (clipped vs unclipped
        signal) and the shift of the noise-free clipped LS from ``[A, B]`` (what BCLS recovers).
    """
    n = G.shape[0]
    lo_l, hi_l = _clip_limits(lo_q, eps, bits)
    if extremes is None:
        extremes = (Psi.min(axis=1), Psi.max(axis=1), Xp.min(axis=1), Xp.max(axis=1))
    if clips_nothing(extremes, lo_q, eps, bits):
        return np.zeros_like(G)  # nothing clipped (checked on the extremes, without clipped copies)
    # an extreme beyond a limit: that sample, at least, is clipped. Only the clipped samples change the Grams:
    # PPc = PP + sum over them of (pc pc' - p p'), likewise XPc; they are looked for only in the channels whose
    # extremes pass a limit (no clipped copy of the data)
    PP, XP = grams if grams is not None else (Psi @ Psi.T, Xp @ Psi.T)
    out = np.zeros(Psi.shape[1], dtype=bool)
    p_lo, p_hi, x_lo, x_hi = extremes
    for rows, low, high in ((Psi, p_lo, p_hi), (Xp, x_lo, x_hi)):
        for a in range(rows.shape[0]):
            if low[a] < lo_l[a]:
                out |= rows[a] < lo_l[a]
            if high[a] > hi_l[a]:
                out |= rows[a] > hi_l[a]
    P, X = Psi[:, out], Xp[:, out]
    Pc = np.clip(P, lo_l[:, None], hi_l[:, None])
    Xc = np.clip(X, lo_l[:n, None], hi_l[:n, None])
    PPc, XPc = PP + (Pc @ Pc.T - P @ P.T), XP + (Xc @ Pc.T - X @ P.T)
    T = Psi.shape[1]
    D = np.diag(np.asarray(eps, dtype=float) ** 2 * variance) * T
    try:
        ls_shift = np.linalg.solve(PPc + D, XPc.T).T - np.linalg.solve(PP + D, XP.T).T
        bcls_shift = np.linalg.solve(PPc, XPc.T).T - G
    except np.linalg.LinAlgError:
        return np.full_like(G, np.inf)
    shift: np.ndarray = np.maximum(np.abs(ls_shift), np.abs(bcls_shift))
    return shift


def _clip_limits(lo_q: np.ndarray, eps: np.ndarray, bits: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """The values the quantizer keeps per channel (the centres of its first and last cells; +-inf if exact)."""
    exact = np.asarray(eps, dtype=float) <= 0
    levels = 2.0 ** np.asarray(bits, dtype=float)
    lo_l = np.where(exact, -np.inf, lo_q + eps / 2)
    hi_l = np.where(exact, np.inf, lo_q + eps * (levels - 0.5))
    return lo_l, hi_l


def clips_nothing(
    extremes: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], lo_q: np.ndarray, eps: np.ndarray, bits: ArrayLike
) -> bool:
    """True if the quantizer clips no sample, judged from the data's extremes ``(Psi_min, Psi_max, Xp_min,
    Xp_max)`` per channel (:meth:`~qsid_core.plant.data.Dataset.extremes`); see :func:`clipping_effect`."""
    lo_l, hi_l = _clip_limits(lo_q, eps, bits)
    p_lo, p_hi, x_lo, x_hi = extremes
    n = x_lo.shape[0]
    return bool(np.all(p_lo >= lo_l) and np.all(p_hi <= hi_l) and np.all(x_lo >= lo_l[:n]) and np.all(x_hi <= hi_l[:n]))
