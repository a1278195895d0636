"""Which sums EDMD with a monomial dictionary needs, and the linear maps that turn them into moments.

Every entry of the lifted moments of one sample is a monomial of the state (the Gram block: one
monomial with the exponents of both features summed; the cross block: a feature of ``x_{t+1}`` times a
feature of ``x_t``). The quantize-lift-accumulate kernel (:mod:`~qsid_core.identification.edmd_kernel`)
therefore adds, per word length, only

* ``SG`` (G,): the sum over regressor samples of every distinct Gram monomial ``x~^Gc[g]``,
* ``XU`` (Lc, m): features times inputs, ``UU`` (m, m): inputs times inputs,
* ``XC`` (Lc, Lc + m): features of ``x~_{t+1}`` times ``[features, inputs]`` of sample ``t``,

of the *plain* quantized data. The de-biased moments (:mod:`~qsid_core.identification.edmd`) and the
expected ones (:mod:`~qsid_core.identification.edmd_limit`) are linear in these sums: per channel, the
de-biased ``k``-th power ``eps^k B_k(x~/eps + 1/2)`` and the expectation ``E[(x + e)^k]`` are
polynomials of degree ``k`` in the channel's value, so a monomial's replacement is a combination of the
monomials below it (same parity per channel where the odd error moments vanish). The feature set ``Ec`` and
the Gram set ``Gc`` are closed under that (:func:`plan_for` adds what a dictionary lacks; ``poly:d`` lacks
nothing, ``identity`` only the constant), so the corrected moments are ``M SG``, ``M XU`` and
``M XC M^T``: one pass over the data serves LS, the de-biased LS and the large-data limit alike.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

__all__ = ["SumPlan", "bernoulli_maps", "expectation_maps", "moments_from_sums", "monomial_map", "plan_for"]


@dataclass(frozen=True, eq=False)
class SumPlan:
    """The kernel's rows and sums for one dictionary and number of inputs.

    The kernel's table ``V`` has the rows ``Ec`` (features), the ``m`` inputs, the extra rows of
    ``Yexp`` and a row of zeros (padding of the tiles), in that order. Each sum of products of two rows
    of ``V`` that the Gram blocks need is one slot of a tile ``(TA[t], TB[t, 0..3])``: the row ``TA[t]``
    times each of four rows, into ``S[TO[t, q]]`` (``-1``: padding), with
    ``S = [SG (G), XU (Lc x m, row-major), UU (m x m, row-major)]``.

    Attributes
    ----------
    E : ndarray of int64, shape (L, n)
        The dictionary's exponents.
    Ec : ndarray of int64, shape (Lc, n)
        The features the kernel lifts: ``E`` first, then the monomials the corrections of ``E`` need.
    Yexp : ndarray of int64, shape (NY, n)
        Every monomial row the kernel computes: ``Ec``, then the extra rows only the Gram sums use.
    Gc : ndarray of int64, shape (G, n)
        The Gram monomials summed.
    TA : ndarray of int64, shape (tiles,)
    TB, TO : ndarray of int64, shape (tiles, 4)
    idx : ndarray of int64, shape (L, L)
        ``Gc[idx[i, j]] == E[i] + E[j]``.
    m : int
        Number of inputs.
    """

    E: np.ndarray
    Ec: np.ndarray
    Yexp: np.ndarray
    Gc: np.ndarray
    TA: np.ndarray
    TB: np.ndarray
    TO: np.ndarray
    idx: np.ndarray
    m: int

    @property
    def L(self) -> int:
        """Number of features of the dictionary."""
        return int(self.E.shape[0])

    @property
    def Lc(self) -> int:
        """Number of features lifted by the kernel."""
        return int(self.Ec.shape[0])

    @property
    def zero_row(self) -> int:
        """Row of ``V`` that stays zero."""
        return int(self.Yexp.shape[0]) + self.m

    def split(self, S: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``SG`` (..., G), ``XU`` (..., Lc, m), ``UU`` (..., m, m) from the slots ``S`` (..., slots)."""
        G, Lc, m = self.Gc.shape[0], self.Lc, self.m
        UU = S[..., G + Lc * m : G + Lc * m + m * m].reshape(S.shape[:-1] + (m, m))
        UU = np.triu(UU) + np.swapaxes(np.triu(UU, 1), -1, -2)  # only a <= b is summed
        return S[..., :G], S[..., G : G + Lc * m].reshape(S.shape[:-1] + (Lc, m)), UU


def _closure(rows: np.ndarray) -> list[tuple[int, ...]]:
    """Every exponent ``beta <= alpha`` with ``beta = alpha`` mod 2 per channel, over the rows ``alpha``."""
    out: set[tuple[int, ...]] = set()
    for a in rows:
        out.update(itertools.product(*[range(int(k) % 2, int(k) + 1, 2) for k in a]))
    return sorted(out, key=lambda e: (sum(e), tuple(-k for k in e)))


def _gram_pairs(Gc: list[tuple[int, ...]], Y: list[tuple[int, ...]]) -> list[tuple[int, int, int]]:
    """``(a, b, g)``: rows of ``Y`` whose product is ``Gc[g]``, ``Y`` extended where no pair exists; rows ``a``
    shared by as many pairs as possible (greedy cover), so the tiles are full."""
    where = {e: q for q, e in enumerate(Y)}
    zero = (0,) * len(Gc[0])
    for mono in Gc:
        if not any(_diff(mono, a) in where for a in Y):  # no product of two rows: its own row, times ones
            for e in (zero, mono):
                if e not in where:
                    where[e] = len(Y)
                    Y.append(e)
    left = set(range(len(Gc)))
    out = []
    while left:
        best = max(range(len(Y)), key=lambda a: (sum(_diff(Gc[g], Y[a]) in where for g in left), -a))
        for g in sorted(left):
            rest = _diff(Gc[g], Y[best])
            if rest is not None and rest in where:
                out.append((best, where[rest], g))
                left.discard(g)
    return out


def _diff(g: tuple[int, ...], a: tuple[int, ...]) -> tuple[int, ...] | None:
    d = tuple(x - y for x, y in zip(g, a, strict=True))
    return d if min(d) >= 0 else None


_PLANS: dict[tuple[bytes, tuple[int, ...], int], SumPlan] = {}


def plan_for(E: np.ndarray, m: int) -> SumPlan:
    """The :class:`SumPlan` of exponents ``E`` (L, n) with ``m`` inputs (cached)."""
    E = np.ascontiguousarray(E, dtype=np.int64)
    key = (E.tobytes(), E.shape, int(m))
    if key in _PLANS:
        return _PLANS[key]
    n = E.shape[1]
    rows = [tuple(int(k) for k in e) for e in E]
    Ec = rows + [e for e in _closure(E) if e not in set(rows)]
    Gc = _closure(np.array(sorted({_sum(a, b) for a in rows for b in rows}), dtype=np.int64).reshape(-1, n))
    Y = list(Ec)
    gram = _gram_pairs(Gc, Y)
    Lc, G = len(Ec), len(Gc)
    vr = [q if q < Lc else q + m for q in range(len(Y))]
    pairs = [(vr[a], vr[b], g) for a, b, g in gram]
    pairs += [(Lc + a, i, G + i * m + a) for a in range(m) for i in range(Lc)]
    pairs += [(Lc + a, Lc + b, G + Lc * m + a * m + b) for a in range(m) for b in range(a, m)]
    zero_row = len(Y) + m
    TA, TB, TO = [], [], []
    for a in dict.fromkeys(p[0] for p in pairs):
        mine = [p for p in pairs if p[0] == a]
        for s in range(0, len(mine), 4):
            chunk = mine[s : s + 4] + [(a, zero_row, -1)] * (4 - len(mine[s : s + 4]))
            TA.append(a)
            TB.append([p[1] for p in chunk])
            TO.append([p[2] for p in chunk])
    gi = {g: i for i, g in enumerate(Gc)}
    plan = SumPlan(
        E=E,
        Ec=np.array(Ec, dtype=np.int64).reshape(-1, n),
        Yexp=np.array(Y, dtype=np.int64).reshape(-1, n),
        Gc=np.array(Gc, dtype=np.int64).reshape(-1, n),
        TA=np.array(TA, dtype=np.int64),
        TB=np.array(TB, dtype=np.int64).reshape(-1, 4),
        TO=np.array(TO, dtype=np.int64).reshape(-1, 4),
        idx=np.array([[gi[_sum(a, b)] for b in rows] for a in rows], dtype=np.int64).reshape(len(rows), len(rows)),
        m=int(m),
    )
    _PLANS[key] = plan
    return plan


def _sum(a: tuple[int, ...], b: tuple[int, ...]) -> tuple[int, ...]:
    return tuple(x + y for x, y in zip(a, b, strict=True))


def bernoulli_maps(Bc: np.ndarray, eps: np.ndarray) -> np.ndarray:
    """Per channel, the de-biased ``k``-th power in powers of ``x~``: ``out[c, k, i] = Bc[k, i] eps_c^(k - i)``.

    Parameters
    ----------
    Bc : ndarray, shape (K + 1, K + 1)
        :func:`~qsid_core.identification.lifting.bernoulli_shifted`.
    eps : ndarray, shape (n,)
        Cell widths (0: the channel is not quantized and its powers stay as they are).

    Returns
    -------
    ndarray, shape (n, K + 1, K + 1)
    """
    K = Bc.shape[0] - 1
    out = np.zeros((len(eps), K + 1, K + 1))
    for c, e in enumerate(np.asarray(eps, dtype=float)):
        if e <= 0:
            out[c] = np.eye(K + 1)
            continue
        for k in range(K + 1):
            out[c, k, : k + 1] = Bc[k, : k + 1] * e ** (k - np.arange(k + 1))
    return out


def expectation_maps(mom: np.ndarray) -> np.ndarray:
    """Per channel, ``E[(x + e)^k] = sum_i C(k, i) E[e^(k - i)] x^i``: ``out[c, k, i]``.

    Parameters
    ----------
    mom : ndarray, shape (K + 1, n)
        ``E[e^l]`` per channel (:func:`~qsid_core.identification.error_moments`).

    Returns
    -------
    ndarray, shape (n, K + 1, K + 1)
    """
    K = mom.shape[0] - 1
    out = np.zeros((mom.shape[1], K + 1, K + 1))
    for k in range(K + 1):
        for i in range(k + 1):
            out[:, k, i] = math.comb(k, i) * mom[k - i]
    return out


def monomial_map(targets: np.ndarray, basis: np.ndarray, maps: np.ndarray) -> np.ndarray:
    """The replacement of each monomial ``targets[t]`` as a combination of the monomials ``basis``.

    ``out[t, q] = prod_c maps[c, targets[t, c], basis[q, c]]`` (zero where ``basis[q] > targets[t]`` in
    some channel, since the maps are lower triangular).

    Parameters
    ----------
    targets : ndarray of int, shape (T, n)
    basis : ndarray of int, shape (Q, n)
        Must hold every monomial a target's replacement uses (:func:`plan_for` makes sure).
    maps : ndarray, shape (n, K + 1, K + 1)
        Per-channel power maps (:func:`bernoulli_maps`, :func:`expectation_maps`).

    Returns
    -------
    ndarray, shape (T, Q)
    """
    out = np.ones((targets.shape[0], basis.shape[0]))
    for c in range(targets.shape[1]):
        out *= maps[c][targets[:, c][:, None], basis[:, c][None, :]]
    return out


def moments_from_sums(
    plan: SumPlan, SG: np.ndarray, XU: np.ndarray, UU: np.ndarray, XC: np.ndarray, maps: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The lifted moments ``PP`` (L + m, L + m) and ``XP`` (L, L + m) of one word length from its sums.

    Parameters
    ----------
    plan : SumPlan
    SG : ndarray, shape (G,)
    XU : ndarray, shape (Lc, m)
    UU : ndarray, shape (m, m)
        Used as given (a correction of the inputs' own squares is the caller's).
    XC : ndarray, shape (Lc, Lc + m)
    maps : ndarray, shape (n, K + 1, K + 1), optional
        Per-channel power maps applied to every monomial (:func:`bernoulli_maps`: the de-biased moments;
        :func:`expectation_maps`: the expected ones); None: the plain moments.
    """
    L, Lc = plan.L, plan.Lc
    if maps is None:
        SGm, MF = SG, np.eye(L, Lc)
    else:
        SGm = monomial_map(plan.Gc, plan.Gc, maps) @ SG
        MF = monomial_map(plan.E, plan.Ec, maps)
    XUm = MF @ XU
    PP = np.empty((L + plan.m, L + plan.m))
    PP[:L, :L] = SGm[plan.idx]
    PP[:L, L:] = XUm
    PP[L:, :L] = XUm.T
    PP[L:, L:] = UU
    XP = np.hstack([MF @ XC[:, :Lc] @ MF.T, MF @ XC[:, Lc:]])
    return PP, XP
