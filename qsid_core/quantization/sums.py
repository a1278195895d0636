"""The running sums over quantized samples that :func:`~qsid_core.quantization.moments.quantized_moments` turns
into Gram matrices, and one step of accumulating them: a chunk of rows quantized at some word lengths, with the
compiled kernel (:mod:`qsid_core.quantization.kernels`) or the numpy reference (:func:`chunk_numpy`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .quantize import draw_dither_units

__all__ = ["ChunkStep", "Sums", "chunk_numpy"]


@dataclass
class Sums:
    """Running sums over the quantized samples ``v`` (in cell units, see :func:`quantized_moments`).

    Index ``j`` is the word length ``bits[j]``; ``g`` the global row (run ``g // S1``, step ``g % S1``).

    Attributes
    ----------
    M : (nb, p, p)   ``sum_g v_g v_g'``
    C : (nb, p, n)   ``sum_g v_{g-1} v_g[:n]'`` over consecutive rows
    sums : (nb, p)   ``sum_g v_g``
    over : (nb,)     overloaded entries
    prev : (nb, p)   ``v`` of the last row seen (carried between chunks)
    v_last, v_first : (nb, runs, p)   ``v`` at the last / first row of every run
    """

    M: np.ndarray
    C: np.ndarray
    sums: np.ndarray
    over: np.ndarray
    prev: np.ndarray
    v_last: np.ndarray
    v_first: np.ndarray

    @classmethod
    def zeros(cls, nb: int, p: int, n: int, runs: int) -> Sums:
        return cls(
            np.zeros((nb, p, p)),
            np.zeros((nb, p, n)),
            np.zeros((nb, p)),
            np.zeros(nb, dtype=np.int64),
            np.zeros((nb, p)),
            np.zeros((nb, runs, p)),
            np.zeros((nb, runs, p)),
        )

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(M, C, sums, over, prev, v_last, v_first)``: the kernel's in-place arguments, in its order."""
        return (self.M, self.C, self.sums, self.over, self.prev, self.v_last, self.v_first)

    def part(self, lo: int, hi: int, runs: int | None = None) -> Sums:
        """The sums of word lengths ``lo:hi`` (views: the kernel adds into these), ``v_last``/``v_first`` cut to
        the first ``runs`` runs when given."""
        r = slice(None) if runs is None else slice(0, runs)
        return Sums(
            self.M[lo:hi],
            self.C[lo:hi],
            self.sums[lo:hi],
            self.over[lo:hi],
            self.prev[lo:hi],
            self.v_last[lo:hi, r],
            self.v_first[lo:hi, r],
        )


def chunk_numpy(
    y: np.ndarray,
    u: np.ndarray | None,
    sub: float,
    scale: np.ndarray,
    half: np.ndarray,
    quant: np.ndarray,
    start: int,
    S1: int,
    acc: Sums,
) -> None:
    """numpy version of :func:`qsid_core.quantization.kernels.accumulate_chunk` (the reference; BLAS for the sums).

    ``scale`` and ``half`` have shape (nb, p); ``quant`` (p,) is False for channels recorded exactly.
    """
    rows, p = y.shape
    n = acc.C.shape[2]
    bb = np.empty_like(y)
    ones = np.ones(rows)
    exact = ~quant
    # rows of this chunk that end / start a run, and the runs they belong to
    lsel = np.arange((S1 - 1 - start) % S1, rows, S1)
    fsel = np.arange((-start) % S1, rows, S1)
    lk, fk = (start + lsel) // S1, (start + fsel) // S1
    for j in range(scale.shape[0]):
        np.multiply(y, scale[j], out=bb)
        keep = bb[:, exact].copy() if exact.any() else None
        if u is not None:
            np.add(bb, u, out=bb)
        h = half[j]
        acc.over[j] += int(np.count_nonzero((bb < -h)[:, quant])) + int(np.count_nonzero((bb > h)[:, quant]))
        np.floor(bb, out=bb)
        np.clip(bb, -h, h - 1, out=bb)
        if u is not None and sub:
            np.subtract(bb, u, out=bb)
        if keep is not None:
            bb[:, exact] = keep
        acc.M[j] += bb.T @ bb
        acc.sums[j] += ones @ bb
        acc.C[j] += (bb[:-1].T @ bb[1:])[:, :n]
        if start > 0:
            acc.C[j] += np.outer(acc.prev[j], bb[0, :n])
        acc.prev[j] = bb[-1]
        acc.v_last[j, lk] = bb[lsel]
        acc.v_first[j, fk] = bb[fsel]


@dataclass(frozen=True)
class ChunkStep:
    """Quantizes rows ``start:end`` of the normalised data ``yc`` at some word lengths and adds to their sums,
    the dither drawn from ``rng`` for those rows, with the compiled kernel or the numpy reference.

    ``S1`` is rows per run (steps + 1); ``quant`` (p,) is False for channels recorded exactly; ``fast`` the
    kernel specialised to the data's size (None: the generic one).
    """

    yc: np.ndarray
    S1: int
    dither: str
    quant: np.ndarray
    compiled: bool
    fast: Callable[..., None] | None

    def __call__(
        self,
        start: int,
        end: int,
        rng: np.random.Generator | None,
        scale: np.ndarray,
        half: np.ndarray,
        acc: Sums,
    ) -> None:
        from . import kernels  # numba loads when a chunk is first quantized, not on import

        sub = 1.0 if self.dither == "subtractive" else 0.0
        y = self.yc[start:end]
        u = draw_dither_units(rng, y.shape, self.dither) if self.dither != "none" and rng is not None else None
        if self.compiled:
            u0 = np.zeros_like(y) if u is None else u
            kernels.accumulate_chunk(
                y, u0, scale, half, start, self.S1, *acc.arrays(), sub=sub, quant=self.quant, kernel=self.fast
            )
        else:
            chunk_numpy(y, u, sub, scale, half, self.quant, start, self.S1, acc)
