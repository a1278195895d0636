"""What the plant asks of any controller: the controllability of a model and the data-rate floor.

* :func:`controllability_margin` -- the relative smallest singular value of the
  controllability matrix (Assumption 2 of the letter asks ``(A^, B^)`` controllable);
* :func:`data_rate_bits` -- the bits per sample any quantized feedback of the plant needs.
"""

from __future__ import annotations

import numpy as np

__all__ = ["data_rate_bits", "controllability_margin", "UNIT_CIRCLE_ROUNDOFF"]

#: ``|lambda| - 1`` at most this is round-off of an eigenvalue on the unit circle (:func:`data_rate_bits`).
UNIT_CIRCLE_ROUNDOFF = 1e-7


def data_rate_bits(A: np.ndarray) -> float:
    """The data-rate theorem's floor: ``sum over |lambda_i| > 1 of log2 |lambda_i|`` bits per sample.

    Any feedback loop that measures the state through a digital channel must send
    more than this many bits per sample to stabilize the plant, whatever the
    controller (Tatikonda & Mitter, IEEE TAC 2004; Nair & Evans, SIAM J. Control
    Optim. 2004). 0 for a stable (or marginally stable) plant: an eigenvalue with
    ``|lambda| <= 1 +`` :data:`UNIT_CIRCLE_ROUNDOFF` counts as on the unit circle (round-off
    of an eigenvalue computed at ``|lambda| = 1``; a double one, as of an undamped mass, moves by
    about the square root of the machine epsilon, 1.5e-8).

    Parameters
    ----------
    A : ndarray, shape (n, n)
    """
    lam = np.abs(np.linalg.eigvals(np.asarray(A, dtype=float)))
    return float(np.sum(np.log2(lam[lam > 1.0 + UNIT_CIRCLE_ROUNDOFF])))


def controllability_margin(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``sigma_min / sigma_max`` of ``[B, AB, ..., A^{n-1}B]`` per model (0: uncontrollable, NaN: no model).

    Each block is scaled by ``max(1, ||A||_2)^-k`` so that fast modes do not
    drown the measure; the controllability matrix's rank is unchanged.

    Parameters
    ----------
    A : ndarray, shape (L, n, n); B : ndarray, shape (L, n, m)

    Returns
    -------
    ndarray, shape (L,)
    """
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    L, n, m = B.shape
    out = np.full(L, np.nan)
    ok = np.all(np.isfinite(A.reshape(L, -1)), axis=1) & np.all(np.isfinite(B.reshape(L, -1)), axis=1)
    if not ok.any():
        return out
    Ao, Bo = A[ok], B[ok]
    scale = np.maximum(1.0, np.linalg.norm(Ao, 2, axis=(1, 2)))[:, None, None]
    blocks, blk = [], Bo
    for _ in range(n):
        blocks.append(blk)
        blk = (Ao @ blk) / scale
    C = np.concatenate(blocks, axis=2)
    s = np.linalg.svd(C, compute_uv=False)
    with np.errstate(invalid="ignore", divide="ignore"):
        out[ok] = np.where(s[:, 0] > 0, s[:, -1] / s[:, 0], 0.0)  # C is n x nm: s has n values
    return out
