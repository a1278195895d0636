"""Theorem 1 of the letter: the large-data limit of least squares from quantized data.

Per-channel form::

    G_pred = [A, B] Sigma (Sigma + D)^-1,   Sigma = Psi_uqz Psi_uqz^T / T,
    D = diag(eps_i**2 / 12)

With one shared eps, ``D = eps**2/12 I`` and this is exactly the letter's
``[A, B] - eps**2 [A, B] (12 Sigma + eps**2 I)^-1`` (Theorem 1, eq. (5)).
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError, check_choice, short_repr
from ..validate import as_float_array

__all__ = ["noise_covariance", "theorem1_prediction"]


def noise_covariance(eps: np.ndarray, dither: str = "subtractive", extra: np.ndarray | float = 0.0) -> np.ndarray:
    """``D = diag(c eps_i**2 + extra_i)``: covariance of the error per channel, shape (p, p).

    ``c`` is 1/12 for subtractive dither and 1/4 for non-subtractive TPDF dither
    (:data:`qsid_core.quantize.ERROR_VARIANCE`); for ``rpdf`` and ``none`` no
    signal-independent variance exists and the nominal 1/12 is used. ``extra``
    (scalar or shape (p,)) adds a known variance such as sensor noise ``sigma**2``.
    """
    from ..quantization.quantize import DITHERS, ERROR_VARIANCE, NOMINAL_VARIANCE

    check_choice("dither", dither, DITHERS)
    e = np.asarray(eps, dtype=float)
    return np.diag(e**2 * ERROR_VARIANCE.get(dither, NOMINAL_VARIANCE) + np.asarray(extra, dtype=float))


def theorem1_prediction(
    G: np.ndarray, Sigma: np.ndarray, eps: np.ndarray, dither: str = "subtractive", extra: np.ndarray | float = 0.0
) -> np.ndarray:
    """Large-data LS limit ``G Sigma (Sigma + D)^-1`` (letter, Theorem 1, per-channel form).

    Parameters
    ----------
    G : ndarray, shape (n, n+m)
        True ``[A, B]``.
    Sigma : ndarray, shape (n+m, n+m)
        ``Psi_uqz Psi_uqz^T / T`` of the unquantized data.
    eps : ndarray, shape (n+m,) or scalar
        Cell width per channel (states first, then inputs).
    dither : str
        Sets ``D`` (see :func:`noise_covariance`).
    extra : float or ndarray, shape (n+m,)
        Further white noise variance per channel (sensor noise), added to ``D``.

    Returns
    -------
    ndarray, shape (n, n+m): the predicted ``[A^, B^]``.
    """
    G = as_float_array("G", G, max_abs=None)
    Sigma = as_float_array("Sigma", Sigma, max_abs=None)
    p = Sigma.shape[0]
    if Sigma.shape != (p, p) or G.ndim != 2 or G.shape[1] != p:
        raise ConfigError(f"G must be (n, p) and Sigma (p, p) with the same p; got {G.shape} and {Sigma.shape}")
    e = as_float_array("eps", eps, ndim_max=1, max_abs=None)
    if e.size not in (1, p) or np.any(e < 0):
        raise ConfigError(
            f"eps must be one cell width >= 0 (0: not quantized) or one per channel ({p}); got {short_repr(e.tolist())}"
        )
    x = as_float_array("extra", extra, ndim_max=1, max_abs=None)
    if x.size not in (1, p) or np.any(x < 0):
        raise ConfigError(f"extra must be one variance >= 0 or one per channel ({p}); got {short_repr(x.tolist())}")
    M = Sigma + noise_covariance(np.broadcast_to(e, (p,)), dither, np.broadcast_to(x, (p,)))
    # G Sigma M^-1 = (M^-1 Sigma G^T)^T (M, Sigma symmetric)
    with np.errstate(over="ignore", invalid="ignore"):
        try:
            out = np.linalg.solve(M, Sigma @ G.T).T
        except np.linalg.LinAlgError:
            raise ConfigError("Sigma + D is singular: no large-data limit exists for these moments") from None
    if not np.all(np.isfinite(out)):
        raise ConfigError("Theorem 1's prediction overflows the floating-point range for these magnitudes")
    return np.asarray(out)
