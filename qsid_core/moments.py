"""Sufficient statistics of quantized data, computed fast.

Least squares (letter, eq. (3), closed form eq. (7)) needs the data only through two Gram matrices::

    PP = Psi~ Psi~^T  (p x p, p = n + m)      XP = X~+ Psi~^T  (n x p)

This module computes them for many word lengths from one stream of unit
dither draws without ever materialising the quantized data set: the states and
inputs are normalised once per quantizer range, and each cache-sized chunk of
samples is quantized for every requested word length while it is hot in cache.
Each state sample is quantized exactly once, so ``x~_{t+1}`` in ``X+`` is the
same number as ``x~_{t+1}`` in ``X`` (as on a real device).

The results are identical (to rounding) to quantizing with
:func:`qsid_core.quantize.quantize` using the same unit dither draws and forming
``Psi`` explicitly; the tests check that.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .data import Dataset
from .quantize import QuantizerSpec, data_ranges, effective_ranges

__all__ = ["Moments", "PreparedData", "prepare", "quantized_moments", "CHUNK_ROWS"]

#: Rows (samples) per chunk; 16384 x 5 doubles = 640 kB: cache-sized, few numpy calls.
CHUNK_ROWS = 16384


@dataclass
class Moments:
    """Gram matrices of (possibly quantized) data.

    Attributes
    ----------
    PP : ndarray, shape (p, p)
        ``Psi Psi^T`` summed over the ``T`` regression samples.
    XP : ndarray, shape (n, p)
        ``X+ Psi^T``.
    T : int
        Number of samples.
    eps : ndarray, shape (p,)
        Cell width per channel (zeros for unquantized data).
    overload_fraction : float
        Fraction of quantized entries whose ``x + w`` left the quantizer range.
    """

    PP: np.ndarray
    XP: np.ndarray
    T: int
    eps: np.ndarray
    overload_fraction: float = 0.0


@dataclass(frozen=True, eq=False)
class PreparedData:
    """A data set normalised for one quantizer range (see :func:`prepare`).

    ``yc`` has shape (rows, p): row ``j*(steps+1) + t`` holds ``[x_t, u_t]`` of
    run ``j`` mapped to ``[-1/2, 1/2]`` per channel; the inputs of the last row
    of each run (which has no input) are 0 (mid range) and are ignored.
    """

    yc: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    n: int
    m: int
    trajectories: int
    steps: int
    exact: Moments

    @property
    def p(self) -> int:
        return self.n + self.m

    @property
    def T(self) -> int:
        return self.trajectories * self.steps


def _exact_moments(data: Dataset) -> Moments:
    Psi, Xp = data.matrices()
    return Moments(PP=Psi @ Psi.T, XP=Xp @ Psi.T, T=Psi.shape[1], eps=np.zeros(Psi.shape[0]))


def prepare(data: Dataset, spec: QuantizerSpec) -> PreparedData:
    """Normalise ``data`` to the quantizer range chosen by ``spec`` (done once, reused for every b)."""
    lo, hi = data_ranges(data.states, data.inputs, spec)
    n, m = data.n, data.m
    J, S = data.trajectories, data.steps
    rows = np.empty((J, S + 1, n + m))
    rows[:, :, :n] = data.states
    rows[:, :S, n:] = data.inputs
    mid = (lo + hi) / 2
    rows[:, S, n:] = mid[n:]
    yc = ((rows - mid) / (hi - lo)).reshape(J * (S + 1), n + m)
    return PreparedData(yc=yc, lo=lo, hi=hi, n=n, m=m, trajectories=J, steps=S, exact=_exact_moments(data))


def quantized_moments(
    prep: PreparedData,
    bits: list[int] | tuple[int, ...],
    spec: QuantizerSpec,
    rng: np.random.Generator | None,
) -> list[Moments]:
    """Gram matrices of the data quantized at each word length in ``bits``.

    Parameters
    ----------
    prep : PreparedData
        From :func:`prepare` with the same ``spec``.
    bits : sequence of int
        Word lengths; the same unit dither draws are used for all of them
        (common random numbers).
    spec : QuantizerSpec
        Dither and guard band.
    rng : numpy Generator or None
        Source of the unit dither U[-1/2, 1/2], one draw per data entry, drawn
        chunk by chunk in a fixed order (so results do not depend on ``bits``).
        Ignored (may be None) when ``spec.dither == "none"``.

    Returns
    -------
    list of Moments, one per entry of ``bits``.
    """
    yc = prep.yc
    N, p = yc.shape
    n, S1 = prep.n, prep.steps + 1
    dithered = spec.dither == "subtractive"
    if dithered and rng is None:
        raise ValueError("subtractive dither needs a random generator")
    nb = len(bits)
    half = [2.0 ** (b - 1) for b in bits]
    scale = [2.0**b - (1.0 if spec.guard else 0.0) for b in bits]
    M = np.zeros((nb, p, p))
    C = np.zeros((nb, p, p))
    sums = np.zeros((nb, p))
    over = np.zeros(nb, dtype=np.int64)
    last_rows = np.arange(S1 - 1, N, S1)
    first_rows = np.arange(0, N, S1)
    # v at the first/last row of every run, per b (for the boundary corrections)
    v_last = np.empty((nb, last_rows.size, p))
    v_first = np.empty((nb, first_rows.size, p))
    prev = np.empty((nb, p))
    buf = np.empty((min(CHUNK_ROWS, N), p))
    ones = np.ones(buf.shape[0])
    for start in range(0, N, CHUNK_ROWS):
        stop = min(start + CHUNK_ROWS, N)
        y = yc[start:stop]
        bb = buf[: stop - start]
        u = rng.uniform(-0.5, 0.5, size=y.shape) if dithered else None
        li, li2 = np.searchsorted(last_rows, [start, stop])
        fi, fi2 = np.searchsorted(first_rows, [start, stop])
        lsel = last_rows[li:li2] - start
        fsel = first_rows[fi:fi2] - start
        for j in range(nb):
            np.multiply(y, scale[j], out=bb)
            if dithered:
                np.add(bb, u, out=bb)
            h = half[j]
            lo_s, hi_s = bb.min(), bb.max()
            if lo_s < -h or hi_s > h:
                # x + w left [lo_q, lo_q + 2^b eps] (padded inputs sit mid-range, never counted)
                over[j] += int(np.count_nonzero(bb < -h)) + int(np.count_nonzero(bb > h))
            np.floor(bb, out=bb)
            if lo_s < -h or hi_s >= h:
                np.clip(bb, -h, h - 1, out=bb)
            if dithered:
                np.subtract(bb, u, out=bb)
            M[j] += bb.T @ bb
            sums[j] += ones[: stop - start] @ bb
            C[j] += bb[:-1].T @ bb[1:]
            if start > 0:
                C[j] += np.outer(prev[j], bb[0])
            prev[j] = bb[-1]
            v_last[j, li:li2] = bb[lsel]
            v_first[j, fi:fi2] = bb[fsel]
    T = prep.T
    total_entries = N * n + T * prep.m
    out: list[Moments] = []
    for j, b in enumerate(bits):
        lo_q, eps = effective_ranges(prep.lo, prep.hi, b, spec.guard)
        a = lo_q + eps * (2.0**b + 1) / 2
        VL, VF = v_last[j], v_first[j]
        Mv = M[j] - VL.T @ VL
        sv = sums[j] - VL.sum(axis=0)
        # pairs (last row of run k, first row of run k+1) are not transitions
        Cv = C[j] - VL[:-1].T @ VF[1:]
        Cv = Cv[:, :n].T  # sum_t v_{t+1}[:n] v_t^T, shape (n, p)
        snext = sums[j][:n] - VF[:, :n].sum(axis=0)
        E = eps
        PP = (E[:, None] * Mv * E[None, :]) + np.outer(E * sv, a) + np.outer(a, E * sv) + T * np.outer(a, a)
        En, an = E[:n], a[:n]
        XP = (En[:, None] * Cv * E[None, :]) + np.outer(En * snext, a) + np.outer(an, E * sv) + T * np.outer(an, a)
        out.append(Moments(PP=PP, XP=XP, T=T, eps=eps, overload_fraction=over[j] / total_entries))
    return out
