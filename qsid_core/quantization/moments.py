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
:func:`qsid_core.quantization.quantize.quantize` using the same unit dither draws and forming
``Psi`` explicitly; the tests check that.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from ..errors import ConfigError, check_choice
from ..plant.data import Dataset
from .quantize import (
    ERROR_VARIANCE,
    NOMINAL_VARIANCE,
    BitsSpec,
    QuantizerSpec,
    bcls_reason,
    channel_bits,
    data_ranges,
    guard_cells,
)
from .sums import ChunkStep, Sums

__all__ = ["Moments", "PreparedData", "exact_moments", "prepare", "quantized_moments", "CHUNK_ROWS", "ENGINES"]

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
    D : ndarray, shape (p,), or None
        Known variance of the error of each channel of ``Psi`` (what BCLS subtracts,
        ``T diag(D)``); None means the subtractive-dither ``eps**2 / 12``.
    bcls_note : str
        Why no known variance exists (then ``D`` is only nominal); "" when it does.
    """

    PP: np.ndarray
    XP: np.ndarray
    T: int
    eps: np.ndarray
    overload_fraction: float = 0.0
    D: np.ndarray | None = None
    bcls_note: str = ""

    @property
    def noise_variance(self) -> np.ndarray:
        """``D`` per channel, shape (p,): the stored one, else ``eps**2 / 12``."""
        if self.D is not None:
            return np.asarray(self.D, dtype=float)
        return np.asarray(self.eps, dtype=float) ** 2 / 12.0


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


def exact_moments(data: Dataset) -> Moments:
    """The Gram matrices of the unquantized data (``PreparedData.exact``), without normalising the data."""
    Psi, Xp = data.matrices()
    return Moments(PP=Psi @ Psi.T, XP=Xp @ Psi.T, T=Psi.shape[1], eps=np.zeros(Psi.shape[0]))


def prepare(data: Dataset, spec: QuantizerSpec, exact: Moments | None = None) -> PreparedData:
    """Normalise ``data`` to the quantizer range chosen by ``spec`` (done once, reused for every b).

    ``exact`` is the unquantized moments to keep (default :func:`exact_moments` of ``data``; a caller that has
    them, or the noise-free data's, passes them).
    """
    lo, hi = data_ranges(data.states, data.inputs, spec)
    n, m = data.n, data.m
    J, S = data.trajectories, data.steps
    rows = np.empty((J, S + 1, n + m))
    rows[:, :, :n] = data.states
    rows[:, :S, n:] = data.inputs
    mid = (lo + hi) / 2
    rows[:, S, n:] = mid[n:]
    rows -= mid  # in place: the same numbers as (rows - mid) / (hi - lo), without two temporaries of the data's size
    rows /= hi - lo
    yc = rows.reshape(J * (S + 1), n + m)
    return PreparedData(
        yc=yc, lo=lo, hi=hi, n=n, m=m, trajectories=J, steps=S, exact=exact_moments(data) if exact is None else exact
    )


#: implementations of :func:`quantized_moments`
ENGINES = ("auto", "numba", "numpy")


def _gram(
    prep: PreparedData,
    chan: tuple[int | None, ...],
    scale: np.ndarray,
    spec: QuantizerSpec,
    acc: Sums,
    j: int,
    upper_only: bool,
) -> Moments:
    """Gram matrices of the quantized data at word length ``b`` from the sums over ``v``.

    Every quantized sample is ``x~ = a + eps * v`` per channel, with
    ``a = lo_q + eps (2^b + 1) / 2 = mid + eps / 2`` (the quantizer's range is symmetric
    about the data range's middle ``mid``); a channel recorded exactly (``chan`` entry
    None) has ``v = y`` in units of ``hi - lo`` and ``a = mid``. The regression
    pairs exclude the last row of every run (no successor) from ``Psi`` and the
    first row of every run from ``X+``; the pairs (last row of run k, first row
    of run k+1) are not transitions. With those corrections (``Mv``, ``sv``,
    ``Cv``, ``snext``)::

        PP = sum_t (a + E v_t)(a + E v_t)'        = E Mv E + (E sv) a' + a (E sv)' + T a a'
        XP = sum_t (a + E v_{t+1})[:n] (a + E v_t)' = E_n Cv E + (E_n snext) a' + a_n (E sv)' + T a_n a'
    """
    n, T = prep.n, prep.T
    quant = np.array([c is not None for c in chan])
    bq = np.array([c if c is not None else 1 for c in chan], dtype=float)
    g = np.array([guard_cells(spec.dither, spec.guard, c) if c is not None else 0.0 for c in chan])
    eps = (prep.hi - prep.lo) / scale  # cell width; the whole range where exact (scale 1)
    a = np.where(quant, prep.lo - g * eps + eps * (2.0**bq + 1) / 2, (prep.lo + prep.hi) / 2)
    VL, VF = acc.v_last[j], acc.v_first[j]
    M = np.triu(acc.M[j]) + np.triu(acc.M[j], 1).T if upper_only else acc.M[j]  # the kernel fills one triangle
    Mv = M - VL.T @ VL
    sv = acc.sums[j] - VL.sum(axis=0)
    Cv = (acc.C[j] - VL[:-1].T @ VF[1:, :n]).T  # sum_t v_{t+1}[:n] v_t', shape (n, p)
    snext = acc.sums[j][:n] - VF[:, :n].sum(axis=0)
    E = eps
    PP = (E[:, None] * Mv * E[None, :]) + np.outer(E * sv, a) + np.outer(a, E * sv) + T * np.outer(a, a)
    En, an = E[:n], a[:n]
    XP = (En[:, None] * Cv * E[None, :]) + np.outer(En * snext, a) + np.outer(an, E * sv) + T * np.outer(an, a)
    total_entries = prep.yc.shape[0] * int(quant[:n].sum()) + T * int(quant[n:].sum())
    eps_q = np.where(quant, eps, 0.0)
    D = eps_q**2 * ERROR_VARIANCE.get(spec.dither, NOMINAL_VARIANCE)
    return Moments(
        PP=PP,
        XP=XP,
        T=T,
        eps=eps_q,
        overload_fraction=acc.over[j] / max(total_entries, 1),
        D=D,
        bcls_note=bcls_reason(spec.dither),
    )


def _cell_counts(
    chans: Sequence[tuple[int | None, ...]], spec: QuantizerSpec
) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64]]:
    """``(quant, half, scale)`` for the channel word lengths ``chans`` (one tuple per b; None: exact):
    which channels are quantized (p,), half the cell count ``2^(b-1)`` and the cells the range spans
    (``2^b`` less the guard band), both (len(chans), p), 1 for exact channels."""
    quant = np.array([c is not None for c in chans[0]])
    half = np.array([[2.0 ** (c - 1) if c is not None else 1.0 for c in ch] for ch in chans])
    scale = np.array(
        [[2.0**c - 2.0 * guard_cells(spec.dither, spec.guard, c) if c is not None else 1.0 for c in ch] for ch in chans]
    )
    return quant, half, scale


def quantized_moments(
    prep: PreparedData,
    bits: list[int] | tuple[int, ...],
    spec: QuantizerSpec,
    rng: np.random.Generator | None,
    engine: str = "auto",
    input_bits: BitsSpec = None,
    state_bits: Sequence[int | str] | None = None,
    runs: Sequence[int] | None = None,
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
        Source of the dither (:func:`~qsid_core.quantization.quantize.draw_dither_units`: one
        U[-1/2, 1/2] draw per data entry, two for ``tpdf``), drawn chunk by chunk
        (:data:`CHUNK_ROWS` rows) in a fixed order (so results do not depend on
        ``bits`` or ``engine``). Ignored (may be None) when ``spec.dither == "none"``.
    engine : {"auto", "numba", "numpy"}
        ``numba``: the fused compiled kernel (:mod:`qsid_core.quantization.kernels`);
        ``numpy``: the vectorised reference; ``auto``: numba when available.
    input_bits : None, "exact", int or tuple
        Word length of the inputs (:func:`~qsid_core.quantization.quantize.channel_bits`); None: the
        same as the states. The dither draws do not depend on it (exact channels
        draw and ignore theirs), so the states' quantization is the same number.
    state_bits : None or tuple of n entries
        Word length of each state (``"b"``: the swept one; an int; ``"exact"``).
    runs : sequence of int, optional
        One per entry of ``bits``: word length ``bits[j]`` quantizes only the first ``runs[j]`` runs of ``prep``
        (nested data sets; default all). Each result is, bit for bit, that of this function on those runs alone
        with ``rng`` in its present state: the dither draws are made once, and a word length whose runs end
        inside a chunk draws its last, shorter chunk from a copy of the generator, as it would alone.

    Returns
    -------
    list of Moments, one per entry of ``bits``.

    Notes
    -----
    In normalised units ``y = (x - mid) / (hi - lo)`` the quantizer with ``2^b``
    cells and unit dither ``u`` gives the sample in cell units
    ``v = clip(floor(y * 2^b + u), -2^(b-1), 2^(b-1) - 1) - u`` (``- u`` only for
    subtractive dither; ``2^b - 2 g`` in place of the first ``2^b`` with a guard band
    of ``g`` cells, :func:`~qsid_core.quantization.quantize.guard_cells`); the quantized value is
    ``a + eps * v`` (see :func:`_gram`). Only sums over ``v`` are accumulated.
    """
    from . import kernels, unrolled

    check_choice("engine", engine, ENGINES)
    if engine == "numba" and not kernels.AVAILABLE:
        raise ConfigError(f"engine 'numba' unavailable: {kernels.REASON}")
    compiled = engine == "numba" or (engine == "auto" and kernels.AVAILABLE)
    if spec.dither != "none" and rng is None:
        raise ValueError(f"{spec.dither} dither needs a random generator")
    J = prep.trajectories
    want = [J] * len(bits) if runs is None else [int(r) for r in runs]
    if len(want) != len(bits) or not all(1 <= r <= J for r in want):
        raise ConfigError(f"runs: one count from 1 to {J} per word length; got {list(want)} for {len(bits)}")
    order = sorted(range(len(bits)), key=lambda j: -want[j])  # the most runs first: a chunk's word lengths are a prefix
    chans = [channel_bits(bits[j], prep.n, prep.m, input_bits, state_bits) for j in order]
    quant, half, scale = _cell_counts(chans, spec)
    acc = Sums.zeros(len(bits), prep.p, prep.n, J)
    rows = [want[j] * (prep.steps + 1) for j in order]
    fast = unrolled.kernel(prep.p, prep.n) if compiled else None  # None: the generic kernel
    step = ChunkStep(prep.yc, prep.steps + 1, spec.dither, quant, compiled, fast)
    _accumulate(step, rows, rng, scale, half, acc)
    got = {}
    for i, j in enumerate(order):
        mine = prep if want[j] == J else replace(prep, yc=prep.yc[: rows[i]], trajectories=want[j])
        got[j] = _gram(mine, chans[i], scale[i], spec, acc.part(i, i + 1, want[j]), 0, compiled)
    return [got[j] for j in range(len(bits))]


def _accumulate(
    step: ChunkStep, rows: list[int], rng: np.random.Generator | None, scale: np.ndarray, half: np.ndarray, acc: Sums
) -> None:
    """Quantize chunk after chunk of the first ``rows[j]`` rows at word length ``j`` (``rows`` falling), the
    dither of a chunk drawn once for the word lengths that quantize all of it and, for one whose rows end inside
    it, drawn again from a copy of the generator as the chunk began (what it alone would draw)."""
    for start in range(0, rows[0], CHUNK_ROWS):
        end = min(start + CHUNK_ROWS, rows[0])
        k = sum(r >= end for r in rows)  # word lengths that quantize the whole chunk
        short = [i for i in range(k, len(rows)) if rows[i] > start]  # ... and those whose rows end inside it
        saved = copy.deepcopy(rng) if short and rng is not None else None
        step(start, end, rng, scale[:k], half[:k], acc.part(0, k))
        for i in short:
            step(start, rows[i], copy.deepcopy(saved), scale[i : i + 1], half[i : i + 1], acc.part(i, i + 1))
