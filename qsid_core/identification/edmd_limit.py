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

import numpy as np

from ..errors import IdentificationError
from ..plant.data import Dataset
from ..quantization import QuantizerSpec, data_ranges, effective_ranges
from .edmd import KoopmanModel, LiftedMoments, edmd
from .edmd_kernel import lifted_sums
from .edmd_plan import SumPlan, expectation_maps, moments_from_sums, plan_for
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


def _expected_moments(
    plan: SumPlan, sums: tuple[np.ndarray, ...], T: int, mom: np.ndarray, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """The lifted moments' expectation over the quantization error with moments ``mom`` (K + 1, n + m), from
    the sums of the unquantized data (:func:`~qsid_core.identification.edmd_kernel.lifted_sums` at ``eps`` 0).

    Each monomial of one sample becomes its expectation, a combination of the monomials below it
    (:func:`~qsid_core.identification.edmd_plan.expectation_maps`); products over two samples have
    independent errors, so their expectations multiply; the inputs' squares gain ``E[e^2]``."""
    SG, XU, UU, XC = (x[0] for x in sums)
    return moments_from_sums(plan, SG, XU, UU + T * np.diag(mom[2, n:]), XC, expectation_maps(mom[:, :n]))


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
    if not isinstance(lifting, MonomialLifting):
        return [
            LargeDataLimit(int(b), None, None, f"no exact limit for the radial functions of {lifting.spec}")
            for b in bits
        ]
    n, m = data.n, data.m
    plan = plan_for(lifting.exponents, m)
    zero = np.zeros((1, n + m))
    sums = lifted_sums(data.states, data.inputs, None, zero, zero, np.ones(1), 0.0, plan)[:4]
    exact_PP, _ = moments_from_sums(plan, *(x[0] for x in sums))
    out = []
    for b in bits:
        _, eps = effective_ranges(lo, hi, int(b), spec.guard, spec.dither)
        mom = error_moments(spec.dither, eps, 2 * int(lifting.exponents.max()))
        if mom is None:
            why = f"the error moments of {spec.dither} dither above the first depend on the signal"
            if spec.dither == "tpdf":
                why = "TPDF dither fixes the error's moments up to the second only (the identity dictionary)"
            out.append(LargeDataLimit(int(b), None, None, f"no exact limit: {why}"))
            continue
        PP, XP = _expected_moments(plan, sums, data.T, mom, n)
        expected = LiftedMoments(PP=PP, XP=XP, T=data.T, eps=np.zeros(n + m))
        try:
            model = edmd(expected, lifting.C, "ls")
        except IdentificationError as exc:
            out.append(LargeDataLimit(int(b), None, None, f"no limit: {exc}"))
            continue
        out.append(LargeDataLimit(int(b), model, (expected.PP - exact_PP) / expected.T))
    return out
