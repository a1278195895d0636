"""Compiled kernels (numba) for the engine's two hot loops, with numpy fallbacks.

* :func:`accumulate_chunk` -- quantize a chunk of normalised samples at every
  word length with the given unit dither draws and accumulate the sums the
  Gram matrices need, in one pass (used by :mod:`qsid_core.quantization.moments`).
* :func:`box_qp_pdas` -- primal-dual active-set iterations for a batch of the
  MPC's condensed box QPs (used by :mod:`qsid_core.control.closed_loop`).

numba compiles on first use (about 1-3 s per kernel) and caches the machine code
on disk (``cache=True``), so later processes (CLI runs, dashboard, pool workers)
load it in a fraction of a second. The cache goes next to this file when that is
writable, else to ``$XDG_CACHE_HOME/qsid/numba`` (default ``~/.cache/qsid/numba``);
an explicit ``NUMBA_CACHE_DIR`` is respected. Without numba (or with
``QSID_NO_NUMBA=1``) :data:`AVAILABLE` is False, callers use their numpy
versions, and :data:`REASON` says why.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["AVAILABLE", "REASON", "accumulate_chunk", "box_qp_pdas", "cache_dir"]

Floats = NDArray[np.float64]
Ints = NDArray[np.int64]
Bools = NDArray[np.bool_]


def cache_dir() -> str:
    """Where numba's cache goes: next to the package if writable, else a per-user cache directory."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return os.environ["NUMBA_CACHE_DIR"]
    here = Path(__file__).resolve().parent
    pyc = here / "__pycache__"
    if os.access(pyc if pyc.exists() else here, os.W_OK):
        return str(pyc)
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return str(base / "qsid" / "numba")


def _load() -> tuple[Any, str]:  # (the numba module, which ships no type information, or None; why not)
    if os.environ.get("QSID_NO_NUMBA"):
        return None, "numba disabled by QSID_NO_NUMBA"
    d = cache_dir()
    if not d.endswith("__pycache__"):  # numba reads NUMBA_CACHE_DIR when it is first imported
        os.environ.setdefault("NUMBA_CACHE_DIR", d)
        try:
            os.makedirs(d, exist_ok=True)
        except OSError as exc:
            return None, f"no writable numba cache directory ({d}: {exc})"
    try:
        import numba
    except ImportError as exc:
        return None, f"numba is not installed ({exc}); using the numpy implementation"
    return numba, ""


_numba, REASON = _load()
#: True when the compiled kernels are used
AVAILABLE = _numba is not None


#: rows per block inside the kernel: the block's quantized samples stay in L1 cache
BLOCK = 256


def _dot_py(x: Floats, y: Floats, k: int) -> float:
    """``sum_{r<k} x[r] y[r]`` (a loop numba vectorises)."""
    acc = 0.0
    for r in range(k):
        acc += x[r] * y[r]
    return acc


def _accumulate_block_py(V: Floats, nr: int, r1: int, M: Floats, C: Floats, sums: Floats, j: int) -> None:
    """Add one block's sums at word length ``j``: ``sums += sum_r v_r``, ``M += sum_r v_r v_r'`` (upper
    triangle) and ``C += sum_r v_{r-1} v_r[:n]'`` over rows ``r1 + 1 .. nr`` (``v_r = V[:, r]``, ``V[:, 0]``
    the row before the block). Any number of channels; :mod:`qsid_core.quantization.unrolled` writes the same sums
    unrolled for one number of channels and states."""
    p = V.shape[0]
    n = C.shape[2]
    for a in range(p):
        Va = V[a, 1 : nr + 1]
        acc = 0.0
        for r in range(nr):
            acc += Va[r]
        sums[j, a] += acc
        for b in range(a, p):
            M[j, a, b] += _dot(Va, V[b, 1 : nr + 1], nr)
    for a in range(p):
        for b in range(n):
            C[j, a, b] += _dot(V[a, r1:nr], V[b, r1 + 1 : nr + 1], nr - r1)


def _accumulate_chunk_py(
    y: Floats,
    u: Floats,
    sub: float,
    quant: Bools,
    scale: Floats,
    half: Floats,
    row0: int,
    S1: int,
    M: Floats,
    C: Floats,
    sums: Floats,
    over: Ints,
    prev: Floats,
    v_last: Floats,
    v_first: Floats,
) -> None:
    """Quantize rows ``y`` at every word length and accumulate (see :func:`accumulate_chunk`)."""
    rows, p = y.shape
    V = np.empty((p, BLOCK + 1))  # V[:, 0] = v of the row before the block, V[:, 1 + r] = v of row r
    yT = np.empty((p, BLOCK))  # the block's samples and draws channel by channel (contiguous loops)
    uT = np.empty((p, BLOCK))
    for s0 in range(0, rows, BLOCK):  # block outer, word length inner: the block's y and u stay in L1 cache
        nr = min(BLOCK, rows - s0)
        g0 = row0 + s0  # global index of the block's first row
        for r in range(nr):
            for a in range(p):
                yT[a, r] = y[s0 + r, a]
                uT[a, r] = u[s0 + r, a]
        for j in range(scale.shape[0]):
            # quantize: v = clip(floor(y * scale + u), -half, half - 1) - sub * u (two roundings, as numpy);
            # overload where y * scale + u leaves [-half, half]; an unquantized channel keeps v = y * scale
            cnt = 0
            for a in range(p):
                s_j, h = scale[j, a], half[j, a]
                V[a, 0] = prev[j, a]
                ya, ua, va = yT[a], uT[a], V[a, 1:]
                if quant[a]:
                    for r in range(nr):
                        t = ya[r] * s_j
                        t = t + ua[r]
                        cnt += (t < -h) | (t > h)
                        va[r] = min(max(np.floor(t), -h), h - 1) - sub * ua[r]
                else:
                    for r in range(nr):
                        va[r] = ya[r] * s_j
            over[j] += cnt
            # the block's sums (no pair of consecutive rows before global row 0)
            _accumulate_block(V, nr, 0 if g0 > 0 else 1, M, C, sums, j)
            for a in range(p):
                prev[j, a] = V[a, nr]
            # v at the last / first row of every run in the block (g % S1 == S1 - 1 / == 0)
            for r in range((S1 - 1 - g0 % S1) % S1, nr, S1):
                for a in range(p):
                    v_last[j, (g0 + r) // S1, a] = V[a, r + 1]
            for r in range((S1 - g0 % S1) % S1, nr, S1):
                for a in range(p):
                    v_first[j, (g0 + r) // S1, a] = V[a, r + 1]


def _chol_solve_py(Hs: Floats, free: Ints, nf: int, L: Floats, rhs: Floats) -> bool:
    """Solve ``H_FF z = rhs`` in place (``F = free[:nf]``) by Cholesky; False if ``H_FF`` is not definite."""
    for a in range(nf):  # L L' = H_FF (lower triangle)
        for b in range(a + 1):
            acc = Hs[free[a], free[b]]
            for c in range(b):
                acc -= L[a, c] * L[b, c]
            if a == b:
                if acc <= 0.0:
                    return False
                L[a, a] = np.sqrt(acc)
            else:
                L[a, b] = acc / L[b, b]
    for a in range(nf):  # forward, then backward substitution
        acc = rhs[a]
        for c in range(a):
            acc -= L[a, c] * rhs[c]
        rhs[a] = acc / L[a, a]
    for a in range(nf - 1, -1, -1):
        acc = rhs[a]
        for c in range(a + 1, nf):
            acc -= L[c, a] * rhs[c]
        rhs[a] = acc / L[a, a]
    return True


def _pdas_one_py(
    Hs: Floats,
    gs: Floats,
    ub: Floats,
    up: Bools,
    lo: Bools,
    iters: int,
    tol: float,
    x: Floats,
    L: Floats,
    rhs: Floats,
    free: Ints,
) -> bool:
    """Primal-dual active-set iterations for one box QP from the guess ``up``/``lo`` (updated in place).

    On True, ``x`` holds the minimiser of ``1/2 x'Hs x + gs'x`` subject to ``|x| <= ub``
    (its KKT conditions checked); False if it did not settle within ``iters`` iterations
    or ``Hs`` restricted to the free variables is not numerically definite.
    """
    nU = gs.shape[0]
    scale = 1.0
    for i in range(nU):
        scale = max(scale, 1.0 + abs(gs[i]))
    for _ in range(iters):
        # fix the active variables at their bound, solve H_FF x_F = -(g_F + H_FA x_A) by Cholesky
        nf = 0
        for i in range(nU):
            if up[i]:
                x[i] = ub[i]
            elif lo[i]:
                x[i] = -ub[i]
            else:
                free[nf] = i
                nf += 1
        for a in range(nf):
            i = free[a]
            acc = -gs[i]
            for j in range(nU):
                if up[j] or lo[j]:
                    acc -= Hs[i, j] * x[j]
            rhs[a] = acc
        if not _chol_solve(Hs, free, nf, L, rhs):
            return False
        for a in range(nf):
            x[free[a]] = rhs[a]
        # KKT: free variables inside the box, multipliers of the fixed ones >= 0
        kkt = True
        for i in range(nU):
            gr = gs[i]
            for j in range(nU):
                gr += Hs[i, j] * x[j]
            if up[i]:
                lam = -gr
            elif lo[i]:
                lam = gr
            else:
                lam = 0.0
                if abs(x[i]) > ub[i] * (1.0 + tol):
                    kkt = False
            if lam < -tol * scale:
                kkt = False
            # next active set: coordinate-wise Newton step y = x - grad / H_ii
            y = x[i] - gr / Hs[i, i]
            up[i] = y > ub[i]
            lo[i] = y < -ub[i]
        if kkt:
            return True
    return False


def _box_qp_pdas_py(
    H: Floats, g: Floats, ub: Floats, upper: Bools, lower: Bools, iters: int, tol: float, U: Floats, ok: Bools
) -> None:
    """Primal-dual active-set iterations for each box QP of a batch (see :func:`box_qp_pdas`)."""
    S, nU = g.shape
    L = np.empty((nU, nU))
    rhs = np.empty(nU)
    free = np.empty(nU, dtype=np.int64)
    x = np.empty(nU)
    for s in range(S):
        up, lo = upper[s].copy(), lower[s].copy()
        if _pdas_one(H[s], g[s], ub, up, lo, iters, tol, x, L, rhs, free):
            for i in range(nU):
                U[s, i] = x[i]
            ok[s] = True


if AVAILABLE:
    _chol_solve = _numba.njit(cache=True, nogil=True)(_chol_solve_py)
    _pdas_one = _numba.njit(cache=True, nogil=True)(_pdas_one_py)
    _box_qp_pdas_nb = _numba.njit(cache=True, nogil=True)(_box_qp_pdas_py)
    _dot = _numba.njit(cache=True, nogil=True, fastmath={"reassoc"})(_dot_py)
    _accumulate_block = _numba.njit(cache=True, nogil=True, fastmath={"reassoc"})(_accumulate_block_py)
    _accumulate_chunk_nb = _numba.njit(cache=True, nogil=True, fastmath={"reassoc"})(_accumulate_chunk_py)
    # "reassoc" lets LLVM vectorise the sums (their order changes: rounding only, ~1e-16 relative);
    # no "contract": y * scale + u stays two roundings, so every quantized sample equals numpy's
else:  # pragma: no cover
    _chol_solve = _chol_solve_py
    _pdas_one = _pdas_one_py
    _box_qp_pdas_nb = None
    _dot = _dot_py
    _accumulate_block = _accumulate_block_py
    _accumulate_chunk_nb = None


def accumulate_chunk(
    y: Floats,
    u: Floats,
    scale: ArrayLike,
    half: ArrayLike,
    row0: int,
    S1: int,
    M: Floats,
    C: Floats,
    sums: Floats,
    over: Ints,
    prev: Floats,
    v_last: Floats,
    v_first: Floats,
    sub: float = 1.0,
    quant: ArrayLike | None = None,
    kernel: Callable[..., None] | None = None,
) -> None:
    """Quantize a chunk of normalised samples at every word length and accumulate, in place.

    For word length ``j`` and channel ``a`` with ``2^b`` cells (``scale[j, a] = 2^b``, less twice the
    guard band in cells; ``half[j, a] = 2^(b-1)``) the quantized sample in cell units is
    ``v = clip(floor(y * scale + u), -half, half - 1) - sub * u`` (``u`` the dither in cell units,
    ``sub`` 1 for subtractive dither, 0 for non-subtractive); the real value is ``a + eps * v`` (see
    :func:`qsid_core.quantization.moments.quantized_moments`).

    Parameters
    ----------
    y : ndarray, shape (rows, p)
        Normalised samples ``[x_t, u_t]`` in ``[-1/2, 1/2]``; global rows ``row0 ..``.
    u : ndarray, shape (rows, p)
        Dither in cell units (U[-1/2, 1/2]; triangular on [-1, 1] for TPDF); zeros
        without dither (adding and subtracting 0 changes no value).
    scale, half : ndarray, shape (nb,) or (nb, p)
        Per word length, or per word length and channel (channels of other word lengths).
    row0 : int
        Global index of the chunk's first row (row ``g`` is step ``g % S1`` of run ``g // S1``).
    S1 : int
        Rows per run (steps + 1).
    M : ndarray, shape (nb, p, p)
        ``sum v v'`` (upper triangle only; mirror it after the last chunk).
    C : ndarray, shape (nb, p, n)
        ``sum_g v_{g-1} v_g[:n]'`` over consecutive global rows.
    sums : ndarray, shape (nb, p)
    over : ndarray of int64, shape (nb,)
        Entries whose ``y * scale + u`` left ``[-half, half]`` (overload).
    prev : ndarray, shape (nb, p)
        ``v`` of the previous global row (carried between chunks).
    v_last, v_first : ndarray, shape (nb, runs, p)
        ``v`` at the last and the first row of every run (for the boundary corrections).
    sub : float
        1.0: the dither is subtracted after quantization; 0.0: it is not.
    quant : ndarray of bool, shape (p,), optional
        False for a channel recorded exactly (no quantization: ``v = y * scale``); default all True.
    kernel : compiled function, optional
        The same kernel specialised to ``p`` channels and ``n`` states (:func:`qsid_core.quantization.unrolled.kernel`);
        default the generic one.
    """
    if not AVAILABLE:
        raise RuntimeError(f"compiled kernels unavailable: {REASON}")
    p = y.shape[1]
    sc, hf = np.asarray(scale, dtype=float), np.asarray(half, dtype=float)
    scale2 = np.ascontiguousarray(np.broadcast_to(sc.reshape(len(sc), -1), (len(sc), p)))
    half2 = np.ascontiguousarray(np.broadcast_to(hf.reshape(len(hf), -1), (len(hf), p)))
    q = np.ones(p, dtype=np.bool_) if quant is None else np.asarray(quant, dtype=np.bool_)
    fn = kernel or _accumulate_chunk_nb
    fn(y, u, float(sub), q, scale2, half2, int(row0), int(S1), M, C, sums, over, prev, v_last, v_first)


def box_qp_pdas(
    H: Floats, g: Floats, ub: ArrayLike, upper: Bools, lower: Bools, iters: int = 8, tol: float = 1e-12
) -> tuple[Floats, Bools]:
    """Compiled :func:`qsid_core.control.condensed_qp.box_qp_batch`: same rule, same KKT check, one problem at a time.

    Each iteration fixes the active variables at their bound and solves the free
    ones, ``H_FF U_F = -(g_F + H_FA U_A)``, by a Cholesky factorisation of
    ``H_FF``; the result is accepted when the free variables are inside the box
    and every multiplier (``-(HU + g)_i`` at an upper, ``+(HU + g)_i`` at a lower
    bound) is non-negative. Returns ``(U (S, nU), ok (S,))``; ``U`` is NaN where
    the problem did not settle within ``iters`` iterations.
    """
    if not AVAILABLE:
        raise RuntimeError(f"compiled kernels unavailable: {REASON}")
    S, nU = g.shape
    U = np.full((S, nU), np.nan)
    ok = np.zeros(S, dtype=np.bool_)
    _box_qp_pdas_nb(
        np.ascontiguousarray(H),
        np.ascontiguousarray(g),
        np.ascontiguousarray(ub, dtype=float),
        upper,
        lower & ~upper,
        int(iters),
        float(tol),
        U,
        ok,
    )
    return U, ok
