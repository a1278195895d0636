"""The quantize-lift-accumulate kernel of EDMD with a monomial dictionary (numba; numpy without it).

One call makes one pass over the raw data (one dither realization) and serves every word length: the
samples are read in blocks of :data:`BLOCK` rows (runs laid end to end; a block that ends inside a run
shares its last row with the next one, so every pair of consecutive samples of a run lies in one block),
and for each block and word length the kernel

* quantizes every channel (the state of every sample once, so ``x~_{t+1}`` of one pair is ``x~_t`` of
  the next, as on a device) and counts the overloaded entries,
* lifts the block into the table ``V`` (rows: the features ``Ec``, the inputs, the extra Gram rows of
  the :class:`~qsid_core.identification.edmd_plan.SumPlan`; columns: samples), with the features and
  inputs of each run's last sample (no regressor) zeroed,
* adds the sums of :mod:`~qsid_core.identification.edmd_plan` (``SG``, ``XU``, ``UU``, ``XC``) as dot
  products of rows of ``V`` across the samples, in register tiles that read each row once for several
  sums (one row times four for the plan's slots, two shifted feature rows times four for the cross
  moments; LLVM vectorises each tile's loop), the cross products of the pairs whose second sample ends a
  run added back from the features kept aside.

Only plain quantized sums are accumulated: the de-biased and expected moments are linear maps of them
(:mod:`~qsid_core.identification.edmd_plan`), so BCLS costs no second pass. The sums are those of the
sample-by-sample definition up to the order of additions (rounding). Without numba, :func:`lifted_sums`
uses :func:`lifted_sums_numpy` (the same sums from whole arrays), which the tests compare with the kernel.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar, cast

import numpy as np

from ..quantization import kernels
from .edmd_plan import SumPlan

__all__ = ["AVAILABLE", "BLOCK", "lifted_sums", "lifted_sums_numpy"]

AVAILABLE = kernels.AVAILABLE
#: Samples per block (the block's table ``V`` stays in the L1 cache for its dot products).
BLOCK = 256

_F = TypeVar("_F", bound=Callable[..., Any])


def _jit(fn: _F, fast: bool = False) -> _F:
    """``fn`` compiled by numba (cached on disk; ``fast``: sums may be reassociated) when available."""
    if not kernels.AVAILABLE:  # pragma: no cover
        return fn
    import numba

    flags: dict[str, Any] = {"fastmath": {"reassoc"}} if fast else {}
    return cast(_F, numba.njit(cache=True, nogil=True, **flags)(fn))


def _quantize_row_py(
    x: np.ndarray,
    w: np.ndarray,
    cw: np.ndarray,
    nb: int,
    lo: float,
    e: float,
    levels: float,
    sub: float,
    out: np.ndarray,
) -> int:
    """``out[:nb]``: the values ``x`` quantized with the dither ``w`` (cells; ``sub`` 1 subtracts it), as
    :func:`~qsid_core.quantization.quantize` does; returns the overloaded entries counted where ``cw`` is 1."""
    cnt = 0
    for k in range(nb):
        s = (x[k] - lo) / e + w[k]
        cnt += ((s < 0.0) | (s > levels)) * cw[k]
        out[k] = lo + e * (min(max(np.floor(s), 0.0), levels - 1.0) + 0.5) - sub * e * w[k]
    return cnt


_quantize_row = _jit(_quantize_row_py)  # no reassociation: the same values as the engine's quantizer


def _tile14_py(A: np.ndarray, B0: np.ndarray, B1: np.ndarray, B2: np.ndarray, B3: np.ndarray, nr: int) -> Any:
    """``sum_{k<nr} A[k] Bq[k]`` for q = 0..3 (each ``A[k]`` read once; one vector sum each)."""
    s0 = s1 = s2 = s3 = 0.0
    for k in range(nr):
        a = A[k]
        s0 += a * B0[k]
        s1 += a * B1[k]
        s2 += a * B2[k]
        s3 += a * B3[k]
    return s0, s1, s2, s3


def _tile24_py(
    A0: np.ndarray, A1: np.ndarray, B0: np.ndarray, B1: np.ndarray, B2: np.ndarray, B3: np.ndarray, nr: int
) -> Any:
    """``sum_{k<nr} Ap[k] Bq[k]`` for p = 0..1, q = 0..3 (eight sums from six rows read once)."""
    s00 = s01 = s02 = s03 = s10 = s11 = s12 = s13 = 0.0
    for k in range(nr):
        a0, a1, b0, b1, b2, b3 = A0[k], A1[k], B0[k], B1[k], B2[k], B3[k]
        s00 += a0 * b0
        s01 += a0 * b1
        s02 += a0 * b2
        s03 += a0 * b3
        s10 += a1 * b0
        s11 += a1 * b1
        s12 += a1 * b2
        s13 += a1 * b3
    return s00, s01, s02, s03, s10, s11, s12, s13


_tile14 = _jit(_tile14_py, fast=True)
_tile24 = _jit(_tile24_py, fast=True)


def _lift_block_py(nb: int, Yexp: np.ndarray, Lc: int, m: int, Pw: np.ndarray, V: np.ndarray) -> None:
    """Rows of ``V`` from the quantized states in ``Pw[:, 1]`` (``Pw[:, 0]`` holds ones): the powers up to
    ``Pw.shape[1] - 1``, then each monomial of ``Yexp`` as the product of its channels' powers."""
    n = Pw.shape[0]
    for c in range(n):
        for p in range(2, Pw.shape[1]):
            Pp, Pq, P1 = Pw[c, p], Pw[c, p - 1], Pw[c, 1]
            for k in range(nb):
                Pp[k] = Pq[k] * P1[k]
    for q in range(Yexp.shape[0]):
        row = V[q if q < Lc else q + m]
        F0 = Pw[0, Yexp[q, 0]]
        if n == 2:
            F1 = Pw[1, Yexp[q, 1]]
            for k in range(nb):
                row[k] = F0[k] * F1[k]
            continue
        for k in range(nb):
            row[k] = F0[k]
        for c in range(1, n):
            Fc = Pw[c, Yexp[q, c]]
            for k in range(nb):
                row[k] *= Fc[k]


def _block_sums_py(
    V: np.ndarray, nb: int, Lc: int, m: int, TA: np.ndarray, TB: np.ndarray, TO: np.ndarray, Z: int,
    last: np.ndarray, nl: int, FL: np.ndarray, S: np.ndarray, XC: np.ndarray,
) -> None:  # fmt: skip
    """Add one block's sums over its regressor columns ``0 .. nb - 2`` (see the module docstring): the slots
    ``S`` by the plan's tiles, the cross products ``XC`` by tiles of two features times four rows (``Z``: the
    zero row that pads them)."""
    nr = nb - 1
    p = Lc + m
    for t in range(TA.shape[0]):
        s = _tile14(V[TA[t]], V[TB[t, 0]], V[TB[t, 1]], V[TB[t, 2]], V[TB[t, 3]], nr)
        for q in range(4):
            if TO[t, q] >= 0:
                S[TO[t, q]] += s[q]
    for i in range(0, Lc, 2):
        i1 = i + 1 if i + 1 < Lc else Z
        for j in range(0, p, 4):
            j1 = j + 1 if j + 1 < p else Z
            j2 = j + 2 if j + 2 < p else Z
            j3 = j + 3 if j + 3 < p else Z
            s8 = _tile24(V[i, 1:], V[i1, 1:], V[j], V[j1], V[j2], V[j3], nr)
            for q in range(min(4, p - j)):
                XC[i, j + q] += s8[q]
                if i + 1 < Lc:
                    XC[i + 1, j + q] += s8[4 + q]
    for s in range(nl):  # pairs whose second sample ends a run: its features were zeroed in V
        k = last[s]
        if k >= 1:
            for i in range(Lc):
                f = FL[i, s]
                for j in range(p):
                    XC[i, j] += f * V[j, k - 1]


_lift_block = _jit(_lift_block_py)
_block_sums = _jit(_block_sums_py, fast=True)


def _load_block_py(
    X: np.ndarray, Uin: np.ndarray, W: np.ndarray, a: int, nb: int, skip: int,
    xb: np.ndarray, wb: np.ndarray, cw: np.ndarray, cwu: np.ndarray, last: np.ndarray,
) -> int:  # fmt: skip
    """Rows ``a .. a + nb - 1`` of the runs laid end to end, channel by channel into ``xb``/``wb`` (n + m, nb);
    ``cw``/``cwu`` 1 where a state/input entry is counted (not the first row when it was the previous block's
    last, no input at a run's last sample); ``last`` the columns ending a run. Returns how many end a run."""
    S1, n = X.shape[1], X.shape[2]
    m = Uin.shape[2]
    nl = 0
    for k in range(nb):
        r = (a + k) // S1
        t = a + k - r * S1
        for c in range(n):
            xb[c, k] = X[r, t, c]
            wb[c, k] = W[r, t, c]
        cw[k] = 0 if k < skip else 1
        ends = t == S1 - 1
        cwu[k] = 0 if ends else cw[k]
        for c in range(m):
            xb[n + c, k] = 0.0 if ends else Uin[r, t, c]
            wb[n + c, k] = 0.0 if ends else W[r, t, n + c]
        if ends:
            last[nl] = k
            nl += 1
    return nl


_load_block = _jit(_load_block_py)


def _kernel_py(
    X: np.ndarray, Uin: np.ndarray, W: np.ndarray, lo_q: np.ndarray, eps: np.ndarray, levels: np.ndarray,
    sub: float, Yexp: np.ndarray, Lc: int, TA: np.ndarray, TB: np.ndarray, TO: np.ndarray,
    S: np.ndarray, XC: np.ndarray, over: np.ndarray, block: int,
) -> None:  # fmt: skip
    """Every block at every word length ``j`` (rows of ``lo_q``, ``eps``; ``eps`` 0: not quantized) into the
    slots ``S[j]``, the cross products ``XC[j]`` and the overload count ``over[j]``, ``block`` samples at a time."""
    R, S1, n = X.shape
    m = Uin.shape[2]
    B = block + 1
    xb, wb = np.empty((n + m, B)), np.empty((n + m, B))
    cw, cwu = np.empty(B, dtype=np.int64), np.empty(B, dtype=np.int64)
    last = np.empty(B, dtype=np.int64)
    Pw = np.ones((n, max(int(Yexp.max()), 1) + 1, B))
    V = np.zeros((Yexp.shape[0] + m + 1, B))  # the last row stays zero
    FL = np.empty((Lc, B))
    total = R * S1
    a, skip = 0, 0
    while a < total:
        nb = min(B, total - a)
        nl = _load_block(X, Uin, W, a, nb, skip, xb, wb, cw, cwu, last)
        for j in range(lo_q.shape[0]):
            for c in range(n + m):
                dst = Pw[c, 1] if c < n else V[Lc + c - n]
                if eps[j, c] > 0:
                    ck = cw if c < n else cwu
                    over[j] += _quantize_row(xb[c], wb[c], ck, nb, lo_q[j, c], eps[j, c], levels[j], sub, dst)
                else:
                    for k in range(nb):
                        dst[k] = xb[c, k]
            _lift_block(nb, Yexp, Lc, m, Pw, V)
            for s in range(nl):  # a run's last sample: its features set aside, its column zeroed
                k = last[s]
                for i in range(Lc):
                    FL[i, s] = V[i, k]
                for i in range(V.shape[0]):
                    V[i, k] = 0.0
            _block_sums(V, nb, Lc, m, TA, TB, TO, V.shape[0] - 1, last, nl, FL, S[j], XC[j])
        ends = nl > 0 and last[nl - 1] == nb - 1
        a, skip = (a + nb, 0) if ends or nb == 1 else (a + nb - 1, 1)


_kernel = _jit(_kernel_py)


def lifted_sums(
    X: np.ndarray,
    Uin: np.ndarray,
    W: np.ndarray | None,
    lo_q: np.ndarray,
    eps: np.ndarray,
    levels: np.ndarray,
    sub: float,
    plan: SumPlan,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The plain sums of the quantized, lifted data at every word length, in one pass over the data.

    Parameters
    ----------
    X : ndarray, shape (runs, steps + 1, n)
        States.
    Uin : ndarray, shape (runs, steps, m)
        Inputs.
    W : ndarray, shape (runs, steps + 1, n + m), or None
        Dither in cell units (the input columns of the last row are unused; None: zeros).
    lo_q, eps : ndarray, shape (J, n + m)
        Quantizer lower bound and cell width per word length and channel (``eps`` 0: recorded exactly).
    levels : ndarray, shape (J,)
        ``2**b`` per word length.
    sub : float
        1.0 subtractive dither, 0.0 non-subtractive.
    plan : SumPlan
        The dictionary's rows and sums (:func:`~qsid_core.identification.edmd_plan.plan_for`).

    Returns
    -------
    SG : ndarray, shape (J, G)
    XU : ndarray, shape (J, Lc, m)
    UU : ndarray, shape (J, m, m)
    XC : ndarray, shape (J, Lc, Lc + m)
    over : ndarray of int64, shape (J,)
        Entries whose ``x + w`` left the range (every state sample once, every input once).
    """
    R, S1, n = X.shape
    m = Uin.shape[2]
    J, Lc = lo_q.shape[0], plan.Lc
    W = np.zeros((R, S1, n + m)) if W is None else W
    S, XC = np.zeros((J, int(plan.TO.max()) + 1)), np.zeros((J, Lc, Lc + m))
    over = np.zeros(J, dtype=np.int64)
    args = (
        np.ascontiguousarray(X, dtype=float), np.ascontiguousarray(Uin, dtype=float),
        np.ascontiguousarray(W, dtype=float), np.ascontiguousarray(lo_q, dtype=float),
        np.ascontiguousarray(eps, dtype=float), np.ascontiguousarray(levels, dtype=float), float(sub),
    )  # fmt: skip
    if not AVAILABLE:  # pragma: no cover
        return lifted_sums_numpy(*args, plan)
    _kernel(*args, plan.Yexp, Lc, plan.TA, plan.TB, plan.TO, S, XC, over, BLOCK)
    return (*plan.split(S), XC, over)


def lifted_sums_numpy(
    X: np.ndarray, Uin: np.ndarray, W: np.ndarray, lo_q: np.ndarray, eps: np.ndarray, levels: np.ndarray,
    sub: float, plan: SumPlan,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """:func:`lifted_sums` from whole arrays (every sample at once per word length; no compiled code)."""
    R, S1, n = X.shape
    m, J = Uin.shape[2], lo_q.shape[0]
    Lc = plan.Lc
    SG, XU = np.zeros((J, plan.Gc.shape[0])), np.zeros((J, Lc, m))
    UU, XC = np.zeros((J, m, m)), np.zeros((J, Lc, Lc + m))
    over = np.zeros(J, dtype=np.int64)
    raw = np.concatenate([X, np.concatenate([Uin, np.zeros((R, 1, m))], axis=1)], axis=2)

    def monomials(v: np.ndarray, exps: np.ndarray) -> np.ndarray:  # (..., n) -> (..., rows of exps)
        out: np.ndarray = np.prod([v[..., c : c + 1] ** exps[:, c] for c in range(n)], axis=0)
        return out

    for j in range(J):
        e = eps[j]
        s = (raw - lo_q[j]) / np.where(e > 0, e, 1.0) + W
        q = lo_q[j] + e * (np.minimum(np.maximum(np.floor(s), 0.0), levels[j] - 1.0) + 0.5) - sub * e * W
        v = np.where(e > 0, q, raw)
        bad = ((s < 0.0) | (s > levels[j])) & (e > 0)
        over[j] = int(bad[..., :n].sum() + bad[:, :-1, n:].sum())
        F = monomials(v[..., :n], plan.Ec)  # (R, S1, Lc)
        Phi = np.concatenate([F, v[..., n:]], axis=2)[:, :-1].reshape(-1, Lc + m)  # regressor samples
        SG[j] = monomials(v[:, :-1, :n].reshape(-1, n), plan.Gc).sum(axis=0)
        XU[j] = Phi[:, :Lc].T @ Phi[:, Lc:]
        UU[j] = Phi[:, Lc:].T @ Phi[:, Lc:]
        XC[j] = F[:, 1:].reshape(-1, Lc).T @ Phi
    return SG, XU, UU, XC, over
