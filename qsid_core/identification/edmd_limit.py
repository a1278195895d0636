"""Where quantized EDMD goes with much data: the lifted analogue of Theorem 1.

Least squares from quantized data fits ``[A_z, B_z] = XP~ PP~^-1`` (:mod:`~qsid_core.identification.edmd`).
Given the unquantized samples, the dither is the only randomness; as the number of samples grows, the
law of large numbers sends each moment to its expectation over the dither, so the estimate goes to::

    G_inf = E[XP~] E[PP~]^-1 = XP (PP + Lambda)^-1 + (a term from E[XP~] - XP)

the *regularized* EDMD of the companion work (Maity & Goswami, arXiv 2410.02803; Ataei, Maity &
Goswami, arXiv 2501.07714): the quantization acts as a data-dependent regularizer ``Lambda = E[PP~] - PP``.
For the identity dictionary ``Lambda = T diag(eps^2/12)`` and ``E[XP~] = XP``: Theorem 1 of the letter.

For a monomial dictionary both expectations are exact polynomials of the unquantized data, because every
entry is a product of per-channel powers of ``x~ = x + e`` with independent errors per channel and
sample (the same argument as the exact de-biasing, run forward)::

    E[(x + e)^k] = sum_l C(k, l) x^(k - l) E[e^l]

which needs the error's moments up to the largest per-channel degree ``k`` of the Gram matrix (twice the
dictionary's degree). They are known exactly for subtractive dither (uniform error,
``E[e^l] = (eps/2)^l / (l + 1)`` for even ``l``, 0 for odd) at every order, and for TPDF non-subtractive
dither up to the second order only (``E[e] = 0``, ``E[e^2] = eps^2/4``): the identity dictionary then, not
a nonlinear one. Radial functions are not polynomials: no finite formula. The prediction assumes no
overload (the guard band keeps the training data inside the range that sets ``eps``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from math import comb

import numpy as np

from ..errors import IdentificationError
from ..plant.data import Dataset
from ..quantization import QuantizerSpec, data_ranges, effective_ranges
from .edmd import KoopmanModel, LiftedMoments, edmd, exact_lifted_moments
from .lifting import Lifting, MonomialLifting

__all__ = ["LARGE_DATA_HYPOTHESES", "LargeDataLimit", "error_moments", "large_data_limit"]

#: What the prediction assumes, as the result lists it.
LARGE_DATA_HYPOTHESES = (
    "many samples (the spread around the limit shrinks like 1/sqrt(T))",
    "no overload (guard band: the error stays independent of the signal)",
    "error moments known up to the Gram matrix's degree (subtractive dither: every order)",
)


@dataclass(frozen=True)
class LargeDataLimit:
    """The large-data limit of LS quantized EDMD at one word length.

    Attributes
    ----------
    bits : int
    model : KoopmanModel or None
        ``E[XP~] E[PP~]^-1`` as a model (None when no exact formula exists: :attr:`note` says why).
    regularizer : ndarray or None, shape (L + m, L + m)
        ``Lambda = (E[PP~] - PP) / T``, the quantization's regularizer per sample.
    note : str
        Why there is no prediction ("" when there is one).
    """

    bits: int
    model: KoopmanModel | None
    regularizer: np.ndarray | None
    note: str = ""


def error_moments(dither: str, eps: np.ndarray, kmax: int) -> np.ndarray | None:
    """``E[e^l]`` of the quantization error for ``l = 0 .. kmax`` per channel, shape (kmax + 1, channels).

    None when some needed moment depends on the signal (non-subtractive dither beyond its order).
    """
    eps = np.asarray(eps, dtype=float)
    kmax = max(int(kmax), 2)  # the inputs' second moments are always needed
    out = np.zeros((kmax + 1,) + eps.shape)
    out[0] = 1.0
    if dither == "subtractive":
        for l in range(2, kmax + 1, 2):
            out[l] = (eps / 2.0) ** l / (l + 1)
        return out
    if dither == "tpdf" and kmax <= 2:
        if kmax == 2:
            out[2] = eps**2 / 4.0
        return out
    return None


def _expected_powers(x: np.ndarray, mom: np.ndarray) -> np.ndarray:
    """``E[(x + e)^k]`` per sample and channel, shape (T, c, K + 1); ``x`` (T, c), ``mom`` (K + 1, c)."""
    K = mom.shape[0] - 1
    pw = np.empty(x.shape + (K + 1,))
    pw[..., 0] = 1.0
    for k in range(1, K + 1):
        pw[..., k] = pw[..., k - 1] * x
    out = np.zeros_like(pw)
    for k in range(K + 1):
        for l in range(0, k + 1):
            if np.any(mom[l]):
                out[..., k] += comb(k, l) * pw[..., k - l] * mom[l]
    return out


def _monomials(P: np.ndarray, E: np.ndarray) -> np.ndarray:
    """``prod_c P[t, c, E[i, c]]``, shape (T, rows of E), from per-channel powers ``P`` (T, n, K + 1)."""
    out = np.ones((P.shape[0], E.shape[0]))
    for c in range(E.shape[1]):
        out *= P[:, c, :][:, E[:, c]]
    return out


def _expected_moments(data: Dataset, lifting: MonomialLifting, mom: np.ndarray) -> LiftedMoments:
    """The lifted moments' expectation over the quantization error with moments ``mom`` (K + 1, n + m)."""
    n, m = data.n, data.m
    E = lifting.exponents
    L = lifting.L
    P = _expected_powers(data.states.reshape(-1, n), mom[:, :n])  # every sample once: its error is drawn once
    runs, steps1 = data.states.shape[:2]
    now = np.arange(runs * steps1).reshape(runs, steps1)[:, :-1].ravel()
    U = data.inputs.reshape(-1, m)  # the same order as ``now``
    GE, inv = np.unique((E[:, None, :] + E[None, :, :]).reshape(L * L, n), axis=0, return_inverse=True)
    Z = _monomials(P, E)  # E[psi(x~)] per sample
    ZZ = _monomials(P[now], GE).sum(axis=0)[inv.ravel()].reshape(L, L)  # E[psi psi^T]: one sample, summed degrees
    Zn = Z[now]
    UU = U.T @ U + len(now) * np.diag(mom[2, n:])
    PP = np.block([[ZZ, Zn.T @ U], [U.T @ Zn, UU]])
    XP = Z[now + 1].T @ np.hstack([Zn, U])  # different samples: independent errors, expectations multiply
    return LiftedMoments(PP=PP, XP=XP, T=len(now), eps=np.zeros(n + m))


def large_data_limit(
    data: Dataset, lifting: Lifting, bits: Sequence[int], spec: QuantizerSpec | None = None
) -> list[LargeDataLimit]:
    """The model LS quantized EDMD tends to with many samples, at every word length in ``bits``.

    Parameters
    ----------
    data : Dataset
        The unquantized training data: states (runs, steps + 1, n), inputs (runs, steps, m).
    lifting : Lifting
    bits : sequence of int
    spec : QuantizerSpec, optional
        The quantizer (default: subtractive dither, per-channel range, guard band): the same cell widths
        as :func:`~qsid_core.identification.quantized_lifted_moments`.

    Returns
    -------
    list of LargeDataLimit, one per word length (``model`` None where no exact formula exists).
    """
    spec = spec or QuantizerSpec()
    lo, hi = data_ranges(data.states, data.inputs, spec)
    exact = exact_lifted_moments(data, lifting) if isinstance(lifting, MonomialLifting) else None
    out = []
    for b in bits:
        _, eps = effective_ranges(lo, hi, int(b), spec.guard, spec.dither)
        if not isinstance(lifting, MonomialLifting) or exact is None:
            out.append(LargeDataLimit(int(b), None, None, f"no exact limit for the radial functions of {lifting.spec}"))
            continue
        mom = error_moments(spec.dither, eps, 2 * int(lifting.exponents.max()))
        if mom is None:
            why = f"the error moments of {spec.dither} dither above the first depend on the signal"
            if spec.dither == "tpdf":
                why = "TPDF dither fixes the error's moments up to the second only (the identity dictionary)"
            out.append(LargeDataLimit(int(b), None, None, f"no exact limit: {why}"))
            continue
        expected = _expected_moments(data, lifting, mom)
        try:
            model = edmd(expected, lifting.C, "ls")
        except IdentificationError as exc:
            out.append(LargeDataLimit(int(b), None, None, f"no limit: {exc}"))
            continue
        out.append(LargeDataLimit(int(b), model, (expected.PP - exact.PP) / expected.T))
    return out
