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
are replaced as one monomial; products over two samples factor). No Python runs per sample.
Compiled with ``cache=True`` like :mod:`qsid_core.quantization.kernels`; the plain Python function is
the fallback without numba.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..quantization import kernels

__all__ = ["AVAILABLE", "accumulate_lifted"]

AVAILABLE = kernels.AVAILABLE


def _accumulate_lifted_py(
    X: np.ndarray,
    Uin: np.ndarray,
    W: np.ndarray,
    lo_q: np.ndarray,
    eps: np.ndarray,
    levels: np.ndarray,
    quant: np.ndarray,
    sub: float,
    E: np.ndarray,
    GE: np.ndarray,
    Bc: np.ndarray,
    unbiased: bool,
    out: tuple[np.ndarray, ...],
) -> None:
    """Accumulate the lifted sums of every run and word length in place (see the module docstring)."""
    SGp, SGu, XUp, XUu, UU, CXp, CXu, CUp, CUu, over = out
    R, S1, n = X.shape
    m = Uin.shape[2]
    J = lo_q.shape[0]
    L = E.shape[0]
    G = GE.shape[0]
    K = Bc.shape[0] - 1
    P = np.empty((n, K + 1))
    Q = np.empty((n, K + 1))
    fp = np.empty(L)
    fu = np.empty(L)
    gp_prev = np.empty(L)
    gu_prev = np.empty(L)
    uq = np.empty(m)
    uq_prev = np.empty(m)
    for r in range(R):
        for j in range(J):
            cnt = 0
            for t in range(S1):
                # quantize the state (and the input while there is one)
                for c in range(n):
                    e = eps[j, c]
                    x = X[r, t, c]
                    if quant[c]:
                        w = W[r, t, c]
                        s = (x - lo_q[j, c]) / e + w
                        cnt += (s < 0.0) | (s > levels[j])
                        k = min(max(math.floor(s), 0.0), levels[j] - 1.0)
                        x = lo_q[j, c] + e * (k + 0.5) - sub * e * w
                    P[c, 0] = 1.0
                    for k2 in range(1, K + 1):
                        P[c, k2] = P[c, k2 - 1] * x
                    if unbiased:
                        for k2 in range(K + 1):
                            if quant[c]:
                                acc = 0.0
                                ek = 1.0
                                for i in range(k2, -1, -1):  # sum_i Bc[k2, i] x^i e^(k2 - i)
                                    acc += Bc[k2, i] * P[c, i] * ek
                                    ek *= e
                                Q[c, k2] = acc
                            else:
                                Q[c, k2] = P[c, k2]
                if t < S1 - 1:
                    for a in range(m):
                        cc = n + a
                        v = Uin[r, t, a]
                        if quant[cc]:
                            e = eps[j, cc]
                            w = W[r, t, cc]
                            s = (v - lo_q[j, cc]) / e + w
                            cnt += (s < 0.0) | (s > levels[j])
                            k = min(max(math.floor(s), 0.0), levels[j] - 1.0)
                            v = lo_q[j, cc] + e * (k + 0.5) - sub * e * w
                        uq[a] = v
                for i in range(L):
                    acc = 1.0
                    for c in range(n):
                        acc *= P[c, E[i, c]]
                    fp[i] = acc
                    if unbiased:
                        acc = 1.0
                        for c in range(n):
                            acc *= Q[c, E[i, c]]
                        fu[i] = acc
                if t >= 1:  # the pair (x_{t-1}, u_{t-1}) -> x_t
                    for i in range(L):
                        for a in range(L):
                            CXp[j, i, a] += fp[i] * gp_prev[a]
                        for a in range(m):
                            CUp[j, i, a] += fp[i] * uq_prev[a]
                    if unbiased:
                        for i in range(L):
                            for a in range(L):
                                CXu[j, i, a] += fu[i] * gu_prev[a]
                            for a in range(m):
                                CUu[j, i, a] += fu[i] * uq_prev[a]
                if t < S1 - 1:  # x_t, u_t as a regressor
                    for g in range(G):
                        acc = 1.0
                        for c in range(n):
                            acc *= P[c, GE[g, c]]
                        SGp[j, g] += acc
                    if unbiased:
                        for g in range(G):
                            acc = 1.0
                            for c in range(n):
                                acc *= Q[c, GE[g, c]]
                            SGu[j, g] += acc
                    for i in range(L):
                        for a in range(m):
                            XUp[j, i, a] += fp[i] * uq[a]
                            if unbiased:
                                XUu[j, i, a] += fu[i] * uq[a]
                    for a in range(m):
                        for b in range(m):
                            UU[j, a, b] += uq[a] * uq[b]
                for i in range(L):
                    gp_prev[i] = fp[i]
                    gu_prev[i] = fu[i] if unbiased else 0.0
                for a in range(m):
                    uq_prev[a] = uq[a]
            over[j] += cnt


_kernel: Callable[..., None]
if AVAILABLE:
    import numba

    _kernel = numba.njit(cache=True, nogil=True, fastmath={"reassoc"})(_accumulate_lifted_py)
else:  # pragma: no cover
    _kernel = _accumulate_lifted_py


def accumulate_lifted(
    X: np.ndarray,
    Uin: np.ndarray,
    W: np.ndarray,
    lo_q: np.ndarray,
    eps: np.ndarray,
    levels: np.ndarray,
    quant: np.ndarray,
    sub: float,
    E: np.ndarray,
    GE: np.ndarray,
    Bc: np.ndarray,
    unbiased: bool,
) -> tuple[np.ndarray, ...]:
    """Quantize, lift and accumulate every run at every word length; returns the sums.

    Parameters
    ----------
    X : ndarray, shape (runs, steps + 1, n)
        States.
    Uin : ndarray, shape (runs, steps, m)
        Inputs.
    W : ndarray, shape (runs, steps + 1, n + m)
        Dither in cell units (the input columns of the last row are unused).
    lo_q, eps : ndarray, shape (J, n + m)
        Quantizer lower bound and cell width per word length and channel.
    levels : ndarray, shape (J,)
        ``2**b`` per word length.
    quant : ndarray of bool, shape (n + m,)
        False for a channel recorded exactly.
    sub : float
        1.0 subtractive dither, 0.0 non-subtractive.
    E : ndarray of int64, shape (L, n)
        Feature exponents.
    GE : ndarray of int64, shape (G, n)
        Gram exponents (pairwise sums of rows of ``E``).
    Bc : ndarray, shape (K + 1, K + 1)
        :func:`~qsid_core.identification.lifting.bernoulli_shifted` up to ``K = max(GE)``.
    unbiased : bool
        Also accumulate the unbiased forms.

    Returns
    -------
    tuple of ndarray
        ``SGp, SGu`` (J, G); ``XUp, XUu`` (J, L, m); ``UU`` (J, m, m); ``CXp, CXu`` (J, L, L);
        ``CUp, CUu`` (J, L, m); ``over`` (J,) int64 (entries that overloaded).
    """
    J, L, m, G = lo_q.shape[0], E.shape[0], Uin.shape[2], GE.shape[0]
    out = (
        np.zeros((J, G)),
        np.zeros((J, G)),
        np.zeros((J, L, m)),
        np.zeros((J, L, m)),
        np.zeros((J, m, m)),
        np.zeros((J, L, L)),
        np.zeros((J, L, L)),
        np.zeros((J, L, m)),
        np.zeros((J, L, m)),
        np.zeros(J, dtype=np.int64),
    )
    _kernel(
        np.ascontiguousarray(X, dtype=float),
        np.ascontiguousarray(Uin, dtype=float),
        np.ascontiguousarray(W, dtype=float),
        np.ascontiguousarray(lo_q, dtype=float),
        np.ascontiguousarray(eps, dtype=float),
        np.ascontiguousarray(levels, dtype=float),
        np.ascontiguousarray(quant, dtype=np.bool_),
        float(sub),
        np.ascontiguousarray(E, dtype=np.int64),
        np.ascontiguousarray(GE, dtype=np.int64),
        np.ascontiguousarray(Bc, dtype=float),
        bool(unbiased),
        out,
    )
    return out
