"""The predicted model error at a fixed budget of bits: Theorem 1's bias plus a finite-data variance.

With ``x~ = x + v`` the recorded next state and ``psi~ = psi + w`` the recorded regressor (``v``, ``w`` the
quantization error under subtractive dither plus the sensor noise: zero mean, independent of the data and of
each other between samples, variance ``d_i`` and fourth moment ``mu4_i`` per channel), an estimator that
subtracts a known ``D_c`` from the Gram matrix (``D_c = 0``: LS; the quantization variance, and the sensor
noise's when known: BCLS) gives to first order

    G^ - G = -G (D - D_c) K + Z K,   K = (Sigma + D - D_c)^-1,

the first term Theorem 1's large-data bias, ``Z`` the mean over the T samples of
``(v_{t+1} - G w_t) psi_t' + v_{t+1} w_t' - G (w_t w_t' - D)``, zero-mean. Its expected squared Frobenius
norm (``N = K K``, ``H = G'G``, ``Sigma_1`` the data's lag-1 moment ``E psi_{t+1} psi_t'``, ``S`` the run
length) is ``V / T`` with

    V = (tr D_x + tr G D G') tr(N Sigma) - 2 (S-1)/S tr(A D_x) tr(N Sigma_1) + tr D_x tr(N D)
        + sum_i H_ii N_ii (mu4_i - d_i^2) + sum_{i != j} d_i d_j (H_ii N_jj + H_ij N_ij),

the second term the correlation of consecutive residuals (``v_{t+1}`` is also the state part of ``w_{t+1}``).
The prediction is ``sqrt(|bias|_F^2 + V / T) / |G|_F``. Where it fails is said in ``docs/science.rst``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..plant.data import Dataset

__all__ = ["lag_moment", "predicted_error", "prefix_moments"]

#: Fourth moment of the uniform error U[-e/2, e/2] over its squared variance (e^4/80 over (e^2/12)^2).
UNIFORM_KURTOSIS = 1.8


def prefix_moments(data: Dataset) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``(PP, XP, lag)``: ``PP[k-1]``, ``XP[k-1]`` the unquantized Gram matrices ``Psi Psi'`` and ``X+ Psi'`` of the
    first ``k`` runs (shapes (runs, p, p) and (runs, n, p), each run's summed once), ``lag`` :func:`lag_moment`."""
    psi = np.concatenate([data.states[:, :-1, :], data.inputs], axis=2)  # (runs, S, p)
    pp = np.cumsum(np.matmul(psi.transpose(0, 2, 1), psi), axis=0)
    xp = np.cumsum(np.matmul(data.states[:, 1:, :].transpose(0, 2, 1), psi), axis=0)
    return pp, xp, _lag(psi)


def _lag(psi: NDArray[np.float64]) -> NDArray[np.float64]:
    a, b = psi[:, 1:, :], psi[:, :-1, :]
    pairs = a.shape[0] * a.shape[1]
    if pairs == 0:
        return np.zeros((psi.shape[2], psi.shape[2]))
    # run by run, then summed: no copy of the data (a sum over both axes at once would gather a transposed copy)
    out: NDArray[np.float64] = np.matmul(a.transpose(0, 2, 1), b).sum(axis=0) / pairs
    return out


def lag_moment(data: Dataset) -> NDArray[np.float64]:
    """``E psi_{t+1} psi_t'`` of the unquantized data over consecutive samples within a run, shape (p, p)."""
    return _lag(np.concatenate([data.states[:, :-1, :], data.inputs], axis=2))


def predicted_error(
    G: NDArray[np.float64],
    Sigma: NDArray[np.float64],
    Sigma1: NDArray[np.float64],
    quant_var: NDArray[np.float64],
    noise_var: NDArray[np.float64],
    corrected: NDArray[np.float64],
    samples: int,
    steps: int,
) -> tuple[float, float]:
    """``(predicted relative error of [A^, B^], its bias part)`` at ``samples`` regression samples.

    Parameters
    ----------
    G : (n, p)
        The true ``[A, B]``.
    Sigma, Sigma1 : (p, p)
        The unquantized data's second moment and lag-1 moment (:func:`lag_moment`).
    quant_var, noise_var : (p,)
        Variance per channel of the quantization error (``eps^2/12``) and of the sensor noise.
    corrected : (p,)
        The variance the estimator subtracts (0 for LS).
    samples, steps : int
        Regression samples T and samples per run S.
    """
    n, p = G.shape
    d = quant_var + noise_var
    mu4 = UNIFORM_KURTOSIS * quant_var**2 + 6.0 * quant_var * noise_var + 3.0 * noise_var**2
    K = np.linalg.inv(Sigma + np.diag(d - corrected))
    nG = float(np.linalg.norm(G))
    bias = -G @ np.diag(d - corrected) @ K
    N = K @ K
    H = G.T @ G
    dx = d[:n]
    first = (dx.sum() + float(np.trace(G @ np.diag(d) @ G.T))) * float(np.trace(N @ Sigma))
    lag = -2.0 * (steps - 1) / steps * float(np.dot(np.diag(G[:, :n]), dx)) * float(np.trace(N @ Sigma1))
    cross = dx.sum() * float(np.dot(np.diag(N), d))
    Hd, Nd = np.diag(H), np.diag(N)
    fourth = float(np.sum(Hd * Nd * (mu4 - d**2)))
    dd = np.outer(d, d)
    np.fill_diagonal(dd, 0.0)
    fourth += float(np.sum(dd * (np.outer(Hd, Nd) + H * N)))
    V = max(first + lag + cross + fourth, 0.0)
    b2 = float(np.sum(bias**2))
    return float(np.sqrt(b2 + V / max(samples, 1)) / nG), float(np.sqrt(b2) / nG)
