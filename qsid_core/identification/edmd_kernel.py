"""The quantize-lift-accumulate kernel of EDMD with a monomial dictionary (numba, numpy-free inner loops).

For every run, every word length and every sample the kernel quantizes the state and the input (each
state sample once, so ``x~_{t+1}`` of one pair is ``x~_t`` of the next, as on a device), builds the
power tables of each channel (plain ``x~^k`` and, optionally, the unbiased ``eps^k B_k(x~/eps + 1/2)``,
:func:`qsid_core.identification.lifting.bernoulli_shifted`), and adds

* ``SG[g]``: the sum over samples of the Gram monomials ``x^GE[g]`` (every pairwise sum of two
  feature exponents: the Gram matrix's feature block is assembled from them),
* ``XU``: features times inputs, ``UU``: inputs times inputs,
* ``CX``: features of ``x_{t+1}`` times features of ``x_t``, ``CU``: features of ``x_{t+1}`` times ``u_t``,

each in the plain form (least squares) and, when asked, the unbiased form (the products of one sample
are replaced as one monomial; products over two samples factor). No Python runs per sample;
the kernel sums the Gram monomials, features times inputs and inputs times inputs itself, and the cross
moments of a block of runs are one matrix product (BLAS) over its consecutive rows.

The generic kernel (:func:`_lift_runs_py`) reads the exponents from arrays. For each dictionary the same
kernel is also written out as Python source (:func:`source`: every power, feature and Gram monomial a
named local, as :mod:`qsid_core.quantization.unrolled` does for the linear kernel), cached in the numba
cache directory under a name hashed from its text and compiled with ``cache=True``, once for LS and once
with the de-biased forms; it is several times faster than the generic one (``benchmarks/bench_koopman.py``,
:doc:`/performance`) and computes the same numbers (a test checks it). Without numba the plain Python function runs.
"""

from __future__ import annotations

import hashlib
import threading
from collections.abc import Callable, Sequence
from typing import Any, TypeVar, cast

import numpy as np

from ..quantization import kernels, unrolled

__all__ = ["AVAILABLE", "MAX_UNROLLED", "NOT_USED", "RUNS_PER_BLOCK", "accumulate_lifted", "source"]

AVAILABLE = kernels.AVAILABLE


_F = TypeVar("_F", bound=Callable[..., Any])


def _quantized_py(v: float, lo: float, e: float, w: float, levels: float, sub: float) -> tuple[float, int]:
    """One value quantized with the dither ``w`` (in cells; ``sub`` 1 subtracts it): (value, 1 if overloaded)."""
    s = (v - lo) / e + w
    k = min(max(np.floor(s), 0.0), levels - 1.0)
    return lo + e * (k + 0.5) - sub * e * w, int((s < 0.0) | (s > levels))


def _monomials_py(F: np.ndarray, E: np.ndarray, out: np.ndarray, add: bool) -> None:
    """``out[i] (+)= prod_c F[c, E[i, c]]``: the monomials of exponents ``E`` from the channels' powers ``F``."""
    for i in range(E.shape[0]):
        acc = 1.0
        for c in range(E.shape[1]):
            acc *= F[c, E[i, c]]
        if add:
            out[i] += acc
        else:
            out[i] = acc


def _jit(fn: _F) -> _F:
    """``fn`` compiled by numba (cached on disk) when the kernels are available, else ``fn`` itself."""
    if not kernels.AVAILABLE:  # pragma: no cover
        return fn
    import numba

    return cast(_F, numba.njit(cache=True, nogil=True)(fn))


_quantized = _jit(_quantized_py)
_monomials = _jit(_monomials_py)


def _powers_py(
    x: float, c: int, K: int, quant: bool, unbiased: bool, Bm: np.ndarray, P: np.ndarray, Q: np.ndarray
) -> None:
    """Row ``c`` of ``P``: ``x**0..x**K``; of ``Q``: their unbiased versions (the same where not quantized)."""
    P[c, 0] = 1.0
    for k2 in range(1, K + 1):
        P[c, k2] = P[c, k2 - 1] * x
    if unbiased:
        for k2 in range(K + 1):
            if quant:
                acc = 0.0
                for i in range(k2, -1, -2):  # B_k(y + 1/2) has the parity of k: every other power
                    acc += Bm[c, k2, i] * P[c, i]
                Q[c, k2] = acc
            else:
                Q[c, k2] = P[c, k2]


_powers = _jit(_powers_py)


def _lift_runs_py(
    X: np.ndarray,
    Uin: np.ndarray,
    W: np.ndarray,
    lo_q: np.ndarray,
    eps: np.ndarray,
    levels: float,
    quant: np.ndarray,
    sub: float,
    E: np.ndarray,
    GE: np.ndarray,
    Bc: np.ndarray,
    unbiased: bool,
    Zp: np.ndarray,
    Zu: np.ndarray,
    SGu: np.ndarray,
    SGp: np.ndarray,
    XUp: np.ndarray,
    XUu: np.ndarray,
    UU: np.ndarray,
) -> int:
    """Quantize and lift a block of runs at one word length; returns the number of overloaded entries.

    Row ``t`` of run ``r`` of ``Zp`` (``Zu``), shape (runs, steps + 1, L + m), gets the plain (unbiased)
    features of ``x~_t`` and then ``u~_t`` (zeros in the last row, which has no input). Over the regressor
    samples (every row but a run's last) it adds the plain (``SGp``) and unbiased (``SGu``) Gram monomials,
    shape (G,), the features times the inputs (``XUp``, ``XUu``, shape (L, m)) and ``u u'`` (``UU``)."""
    R, S1, n = X.shape
    m = Uin.shape[2]
    L = E.shape[0]
    K = Bc.shape[0] - 1
    P = np.empty((n, Bc.shape[0]))
    Q = np.empty((n, Bc.shape[0]))
    # Bm[c, k, i] = Bc[k, i] eps_c^(k - i): the coefficients of the unbiased k-th power of channel c
    Bm = np.zeros((n, Bc.shape[0], Bc.shape[0]))
    for c in range(n):
        for k2 in range(Bc.shape[0]):
            for i in range(k2 + 1):
                Bm[c, k2, i] = Bc[k2, i] * eps[c] ** (k2 - i)
    cnt = 0
    for r in range(R):
        for t in range(S1):
            for c in range(n):
                x = X[r, t, c]
                if quant[c]:
                    x, o = _quantized(x, lo_q[c], eps[c], W[r, t, c], levels, sub)
                    cnt += o
                _powers(x, c, K, quant[c], unbiased, Bm, P, Q)
            _monomials(P, E, Zp[r, t, :L], False)
            if unbiased:
                _monomials(Q, E, Zu[r, t, :L], False)
            if t == S1 - 1:
                Zp[r, t, L:] = 0.0
                if unbiased:
                    Zu[r, t, L:] = 0.0
                continue
            _monomials(P, GE, SGp, True)
            if unbiased:
                _monomials(Q, GE, SGu, True)
            for a in range(m):
                cc = n + a
                v = Uin[r, t, a]
                if quant[cc]:
                    v, o = _quantized(v, lo_q[cc], eps[cc], W[r, t, cc], levels, sub)
                    cnt += o
                Zp[r, t, L + a] = v
                if unbiased:
                    Zu[r, t, L + a] = v
            for a in range(m):
                v = Zp[r, t, L + a]
                for i in range(L):
                    XUp[i, a] += Zp[r, t, i] * v
                    if unbiased:
                        XUu[i, a] += Zu[r, t, i] * v
                for b in range(m):
                    UU[a, b] += v * Zp[r, t, L + b]
    return cnt


_kernel: Callable[..., int] = _jit(_lift_runs_py)

#: Runs lifted per block (the block's features stay in cache for the products).
RUNS_PER_BLOCK = 64
#: Why no specialised kernel is used for a dictionary (by its source file's name; empty while it is).
NOT_USED: dict[str, str] = {}
_LOADED: dict[str, Callable[..., int] | None] = {}
_LOCK = threading.Lock()


def _mono(prefix: str, e: Sequence[int]) -> str:
    """The product of the channels' powers ``prefix{c}_{e[c]}`` (``1.0`` for the constant)."""
    terms = [f"{prefix}{c}_{k}" for c, k in enumerate(e) if k > 0]
    return " * ".join(terms) if terms else "1.0"


def source(E: np.ndarray, GE: np.ndarray, K: int, m: int, unbiased: bool) -> str:
    """The kernel of :func:`_lift_runs_py` written out for one dictionary and one form (``unbiased`` or not):
    every power, feature and running sum a named local (no index arrays, no branch on the form), so LLVM
    keeps them in registers. Same arguments and results (its own ``unbiased`` argument is not read)."""
    n, L, G = E.shape[1], E.shape[0], GE.shape[0]
    i4, i3 = " " * 16, " " * 12
    out = [
        '"""Generated by qsid_core.identification.edmd_kernel for one dictionary; do not edit (rewritten as needed)."""',
        "import numba",
        "import numpy as np",
        "",
        "",
        "@numba.njit(cache=True, nogil=True)",
        "def kernel(X, Uin, W, lo_q, eps, levels, quant, sub, E, GE, Bc, unbiased, Zp, Zu, SGu, SGp, XUp, XUu, UU):",
        "    R, S1 = X.shape[0], X.shape[1]",
        "    cnt = 0",
    ]
    out += [f"    lo{c}, e{c}, q{c} = lo_q[{c}], eps[{c}], quant[{c}]" for c in range(n + m)]
    if unbiased:
        for c in range(n):
            for k in range(K + 1):
                out += [f"    b{c}_{k}_{i} = Bc[{k}, {i}] * e{c} ** {k - i}" for i in range(k % 2, k + 1, 2)]
    sums = [f"sp{g}" for g in range(G)] + [f"xp{i}_{a}" for i in range(L) for a in range(m)]
    sums += [f"uu{a}_{b}" for a in range(m) for b in range(m)]
    if unbiased:
        sums += [f"sg{g}" for g in range(G)] + [f"xu{i}_{a}" for i in range(L) for a in range(m)]
    out += [f"    {v} = 0.0" for v in sums]
    out += ["    for r in range(R):", "        for t in range(S1):"]

    def quantized(v: str, c: int, src: str, w: str, ind: str) -> list[str]:
        return [
            f"{ind}{v} = {src}",
            f"{ind}if q{c}:",
            f"{ind}    w = {w}",
            f"{ind}    s = ({v} - lo{c}) / e{c} + w",
            f"{ind}    cnt += (s < 0.0) | (s > levels)",
            f"{ind}    {v} = lo{c} + e{c} * (min(max(np.floor(s), 0.0), levels - 1.0) + 0.5) - sub * e{c} * w",
        ]

    for c in range(n):
        out += quantized(f"x{c}", c, f"X[r, t, {c}]", f"W[r, t, {c}]", i3)
        out.append(f"{i3}p{c}_1 = x{c}")
        out += [f"{i3}p{c}_{k} = p{c}_{k - 1} * x{c}" for k in range(2, K + 1)]
    out += [f"{i3}f{i} = {_mono('p', E[i])}" for i in range(L)]
    out += [f"{i3}Zp[r, t, {i}] = f{i}" for i in range(L)]
    if unbiased:
        for c in range(n):
            for k in range(1, K + 1):
                terms = " + ".join(f"b{c}_{k}_{i} * p{c}_{i}" if i else f"b{c}_{k}_0" for i in range(k % 2, k + 1, 2))
                out.append(f"{i3}u{c}_{k} = ({terms}) if q{c} else p{c}_{k}")
        out += [f"{i3}g{i} = {_mono('u', E[i])}" for i in range(L)]
        out += [f"{i3}Zu[r, t, {i}] = g{i}" for i in range(L)]
    out.append(f"{i3}if t == S1 - 1:")
    out += [f"{i4}Zp[r, t, {L + a}] = 0.0" for a in range(m)]
    if unbiased:
        out += [f"{i4}Zu[r, t, {L + a}] = 0.0" for a in range(m)]
    out.append(f"{i3}else:")
    out += [f"{i4}sp{g} += {_mono('p', GE[g])}" for g in range(G)]
    if unbiased:
        out += [f"{i4}sg{g} += {_mono('u', GE[g])}" for g in range(G)]
    for a in range(m):
        out += quantized(f"v{a}", n + a, f"Uin[r, t, {a}]", f"W[r, t, {n + a}]", i4)
        out.append(f"{i4}Zp[r, t, {L + a}] = v{a}")
        out += [f"{i4}xp{i}_{a} += f{i} * v{a}" for i in range(L)]
        if unbiased:
            out.append(f"{i4}Zu[r, t, {L + a}] = v{a}")
            out += [f"{i4}xu{i}_{a} += g{i} * v{a}" for i in range(L)]
    out += [f"{i4}uu{a}_{b} += v{a} * v{b}" for a in range(m) for b in range(m)]
    out += [f"    SGp[{g}] += sp{g}" for g in range(G)]
    out += [f"    XUp[{i}, {a}] += xp{i}_{a}" for i in range(L) for a in range(m)]
    out += [f"    UU[{a}, {b}] += uu{a}_{b}" for a in range(m) for b in range(m)]
    if unbiased:
        out += [f"    SGu[{g}] += sg{g}" for g in range(G)]
        out += [f"    XUu[{i}, {a}] += xu{i}_{a}" for i in range(L) for a in range(m)]
    out += ["    return cnt", ""]
    return "\n".join(out)


def _specialised(E: np.ndarray, GE: np.ndarray, K: int, m: int, unbiased: bool) -> Callable[..., int] | None:
    """The compiled kernel for this dictionary and form (written once to the numba cache directory), or None."""
    text = source(E, GE, K, m, unbiased)
    name = "qsid_lift_" + hashlib.sha1(text.encode()).hexdigest()[:16]
    with _LOCK:
        if name in _LOADED:
            return _LOADED[name]
        fn: Callable[..., int] | None = None
        if not AVAILABLE:
            NOT_USED[name] = f"compiled kernels unavailable: {kernels.REASON}"
        elif E.shape[0] > MAX_UNROLLED:
            NOT_USED[name] = f"{E.shape[0]} features: not specialised (at most {MAX_UNROLLED})"
        else:
            try:
                fn = unrolled.import_generated(name, text).kernel
            except Exception as exc:  # any failure: the generic kernel computes the same sums
                NOT_USED[name] = f"{type(exc).__name__}: {exc}"
        _LOADED[name] = fn
        return fn


#: Up to this many features the kernel is written out for the dictionary.
MAX_UNROLLED = 60


def _add_cross(Z: np.ndarray, L: int, XP: np.ndarray) -> None:
    """Add one block's ``Z+ Phi^T`` from the lifted rows ``Z`` (runs, steps + 1, L + m), in place.

    ``Z`` read as one table of consecutive rows: the products of all neighbouring pairs of rows, less the
    pairs that straddle two runs (a run's last row has inputs 0, so only their feature block).
    """
    Zf = Z.reshape(-1, Z.shape[2])
    XP += (Zf[1:].T @ Zf[:-1])[:L]
    XP[:, :L] -= Z[1:, 0, :L].T @ Z[:-1, -1, :L]


def accumulate_lifted(
    X: np.ndarray,
    Uin: np.ndarray,
    W: np.ndarray,
    lo_q: np.ndarray,
    eps: np.ndarray,
    levels: np.ndarray,
    sub: float,
    E: np.ndarray,
    GE: np.ndarray,
    idx: np.ndarray,
    Bc: np.ndarray,
    unbiased: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Quantize, lift and accumulate every run at every word length.

    Parameters
    ----------
    X : ndarray, shape (runs, steps + 1, n)
        States.
    Uin : ndarray, shape (runs, steps, m)
        Inputs.
    W : ndarray, shape (runs, steps + 1, n + m)
        Dither in cell units (the input columns of the last row are unused).
    lo_q, eps : ndarray, shape (J, n + m)
        Quantizer lower bound and cell width per word length and channel (``eps`` 0: recorded exactly).
    levels : ndarray, shape (J,)
        ``2**b`` per word length.
    sub : float
        1.0 subtractive dither, 0.0 non-subtractive.
    E : ndarray of int64, shape (L, n)
        Feature exponents.
    GE : ndarray of int64, shape (G, n)
        Gram exponents (the distinct pairwise sums of rows of ``E``).
    idx : ndarray of int, shape (L, L)
        ``GE[idx[i, j]] == E[i] + E[j]``.
    Bc : ndarray, shape (K + 1, K + 1)
        :func:`~qsid_core.identification.lifting.bernoulli_shifted` up to ``K = max(GE)``.
    unbiased : bool
        Also form the de-biased moments.

    Returns
    -------
    PP : ndarray, shape (J, L + m, L + m)
    XP : ndarray, shape (J, L, L + m)
    PPu, XPu : ndarray, same shapes (zeros unless ``unbiased``)
    over : ndarray of int64, shape (J,)
        Entries whose ``x + w`` left the range.
    """
    R, S1, n = X.shape
    m = Uin.shape[2]
    J, L = lo_q.shape[0], E.shape[0]
    p = L + m
    XP, XPu, over = np.zeros((J, L, p)), np.zeros((J, L, p)), np.zeros(J, dtype=np.int64)
    quant = np.asarray(eps[0] > 0, dtype=np.bool_)
    E64, GE64 = np.ascontiguousarray(E, dtype=np.int64), np.ascontiguousarray(GE, dtype=np.int64)
    Bc = np.ascontiguousarray(Bc, dtype=float)
    SGp, SGu = np.zeros((J, GE.shape[0])), np.zeros((J, GE.shape[0]))
    XUp, XUu, UU = np.zeros((J, L, m)), np.zeros((J, L, m)), np.zeros((J, m, m))
    kern = _specialised(E64, GE64, Bc.shape[0] - 1, m, bool(unbiased)) or _kernel
    for r0 in range(0, R, RUNS_PER_BLOCK):
        Xb = np.ascontiguousarray(X[r0 : r0 + RUNS_PER_BLOCK], dtype=float)
        Ub = np.ascontiguousarray(Uin[r0 : r0 + RUNS_PER_BLOCK], dtype=float)
        Wb = np.ascontiguousarray(W[r0 : r0 + RUNS_PER_BLOCK], dtype=float)
        rb = Xb.shape[0]
        Zp = np.empty((rb, S1, p))
        Zu = np.empty((rb, S1, p) if unbiased else (1, 1, p))
        for j in range(J):
            over[j] += kern(
                Xb, Ub, Wb, lo_q[j], eps[j], float(levels[j]), quant, float(sub), E64, GE64, Bc, bool(unbiased),
                Zp, Zu, SGu[j], SGp[j], XUp[j], XUu[j], UU[j],
            )  # fmt: skip
            _add_cross(Zp, L, XP[j])
            if unbiased:
                _add_cross(Zu, L, XPu[j])
    PP = _gram(SGp, XUp, UU, idx)
    if not unbiased:
        return PP, XP, np.zeros_like(PP), XPu, over
    UUu = UU - R * (S1 - 1) * np.einsum("ja,ab->jab", eps[:, n:] ** 2 / 12.0, np.eye(m))
    return PP, XP, _gram(SGu, XUu, UUu, idx), XPu, over


def _gram(SG: np.ndarray, XU: np.ndarray, UU: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """The Gram matrices, shape (J, L + m, L + m), from their blocks: the summed Gram monomials ``SG`` (J, G)
    placed by ``idx`` (L, L), features times inputs ``XU`` (J, L, m) and inputs times inputs ``UU`` (J, m, m)."""
    L = idx.shape[0]
    PP = np.empty((XU.shape[0], L + XU.shape[2], L + XU.shape[2]))
    PP[:, :L, :L] = SG[:, idx]
    PP[:, :L, L:] = XU
    PP[:, L:, :L] = XU.transpose(0, 2, 1)
    PP[:, L:, L:] = UU
    return PP
