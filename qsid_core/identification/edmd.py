"""EDMD with control from (quantized) data, and its exact de-biasing for monomial dictionaries.

The lifted predictor ``z+ = A_z z + B_z u`` with ``z = psi(x)`` (:mod:`qsid_core.identification.lifting`)
is fitted by least squares (Korda & Mezic 2018)::

    [A_z, B_z] = Z+ Phi^T (Phi Phi^T)^-1,    Phi = [psi(x_t); u_t],  Z+ = psi(x_{t+1})

from the moments ``PP = Phi Phi^T`` ((L + m) x (L + m)) and ``XP = Z+ Phi^T`` (L x (L + m)).

**Exact de-biasing.** With subtractive uniform dither ``x~ = x + e``, ``e ~ U[-eps/2, eps/2]``
independent of ``x`` and between channels and samples (no overload: the guard band), the Bernoulli
polynomials give ``E[eps^k B_k(x~/eps + 1/2)] = x^k``. A monomial of one sample is a product over
channels of such powers (independent dither per channel), so each entry of ``Phi Phi^T`` -- one
monomial with the exponents of both features summed per channel -- is replaced by its unbiased
polynomial; ``Z+ Phi^T`` pairs ``x_{t+1}`` with ``x_t`` (independent dither), so the unbiased features
of each simply multiply. The result has the expectation of the unquantized moments: EDMD from it is
consistent at any word length. For the identity dictionary this is the letter's BCLS
(``x~^2 - eps^2/12`` on the diagonal).

**Where it does not hold.** Non-subtractive dither (TPDF, RPDF) or none: the error is not independent
uniform noise, the Bernoulli identity fails for powers above the first, and the correction applied
anyway is only nominal (:attr:`LiftedMoments.note` says so; the sweeps show the bias left). Radial basis
functions are not polynomials: no finite correction exists, and ``bcls`` falls back to LS with a note.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import IdentificationError, check_choice
from ..plant.data import Dataset
from ..quantization import QuantizerSpec, data_ranges, draw_dither_units, effective_ranges, quantize
from .edmd_kernel import lifted_sums
from .edmd_plan import bernoulli_maps, moments_from_sums, plan_for
from .identify import ESTIMATORS, least_squares
from .lifting import Lifting, MonomialLifting, bernoulli_shifted

__all__ = [
    "KoopmanModel",
    "LiftedMoments",
    "edmd",
    "exact_lifted_moments",
    "lifted_error",
    "prediction_error",
    "prediction_errors",
    "quantized_lifted_moments",
    "quantized_lifted_realizations",
]


@dataclass
class LiftedMoments:
    """The lifted Gram matrices of one data set at one word length.

    Attributes
    ----------
    PP : ndarray, shape (L + m, L + m)
        ``Phi~ Phi~^T`` of the quantized data (what LS uses).
    XP : ndarray, shape (L, L + m)
        ``Z~+ Phi~^T``.
    T : int
        Number of samples.
    eps : ndarray, shape (n + m,)
        Cell width per channel (zeros: unquantized).
    PPu, XPu : ndarray or None
        The de-biased moments (None when not computed or no correction exists).
    overload_fraction : float
        Share of quantized entries whose ``x + w`` left the range.
    note : str
        Why the de-biased moments are not exact or absent ("" when they are exact).
    """

    PP: np.ndarray
    XP: np.ndarray
    T: int
    eps: np.ndarray
    PPu: np.ndarray | None = None
    XPu: np.ndarray | None = None
    overload_fraction: float = 0.0
    note: str = ""


@dataclass
class KoopmanModel:
    """A lifted linear predictor ``z+ = A z + B u``, ``x = C z``.

    Attributes
    ----------
    A : ndarray, shape (L, L)
    B : ndarray, shape (L, m)
    C : ndarray, shape (n, L)
    estimator : str
        The estimator used (``"ls"`` after a fallback).
    fallback : bool
        True if ``bcls`` was asked for and LS used.
    note : str
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    estimator: str
    fallback: bool = False
    note: str = ""

    @property
    def G(self) -> np.ndarray:
        """``[A, B]``, shape (L, L + m)."""
        return np.hstack([self.A, self.B])


def _moments(Z: np.ndarray, U: np.ndarray, Zp: np.ndarray, eps: np.ndarray) -> LiftedMoments:
    Phi = np.hstack([Z, U])
    return LiftedMoments(PP=Phi.T @ Phi, XP=Zp.T @ Phi, T=int(Phi.shape[0]), eps=eps)


def exact_lifted_moments(data: Dataset, lifting: Lifting) -> LiftedMoments:
    """The lifted moments of unquantized data (the reference every quantized estimate is compared with)."""
    n, m = data.n, data.m
    if isinstance(lifting, MonomialLifting):  # the compiled kernel's sums, nothing quantized
        plan = plan_for(lifting.exponents, m)
        zero = np.zeros((1, n + m))
        SG, XU, UU, XC, _ = lifted_sums(data.states, data.inputs, None, zero, zero, np.ones(1), 0.0, plan)
        PP, XP = moments_from_sums(plan, SG[0], XU[0], UU[0], XC[0])
        return LiftedMoments(PP=PP, XP=XP, T=data.T, eps=np.zeros(n + m))
    Z = lifting.lift(data.states)  # every state lifted once: (runs, steps + 1, L)
    L = Z.shape[-1]
    U = data.inputs.reshape(-1, data.m)
    return _moments(Z[:, :-1].reshape(-1, L), U, Z[:, 1:].reshape(-1, L), np.zeros(data.n + data.m))


def quantized_lifted_moments(
    data: Dataset,
    lifting: Lifting,
    bits: Sequence[int],
    spec: QuantizerSpec | None = None,
    seed: int | np.random.SeedSequence = 0,
    unbiased: bool = True,
) -> list[LiftedMoments]:
    """Quantize ``data`` at every word length in ``bits`` (one dither draw shared by all) and lift.

    Parameters
    ----------
    data : Dataset
        States (runs, steps + 1, n), inputs (runs, steps, m).
    lifting : Lifting
    bits : sequence of int
        Word lengths (every state and input channel).
    spec : QuantizerSpec, optional
        Dither, range and guard band (default: subtractive, per-channel range, guard band on).
    seed : int or numpy SeedSequence
        Seed of the dither draws.
    unbiased : bool
        Also compute the de-biased moments (monomial dictionaries only).

    Returns
    -------
    list of LiftedMoments, one per word length.
    """
    return quantized_lifted_realizations(data, lifting, bits, spec, [seed], unbiased)[0]


def quantized_lifted_realizations(
    data: Dataset,
    lifting: Lifting,
    bits: Sequence[int],
    spec: QuantizerSpec | None = None,
    seeds: Sequence[int | np.random.SeedSequence] = (0,),
    unbiased: bool = True,
) -> list[list[LiftedMoments]]:
    """:func:`quantized_lifted_moments` for several dither realizations, ``[realization][word length]``.

    The ranges, cell widths and sums' plan are worked out once; each realization is one pass of the
    compiled kernel over the data (every word length inside it). ``seeds[k]`` gives the same moments as
    ``quantized_lifted_moments(..., seed=seeds[k])``.
    """
    spec = spec or QuantizerSpec()
    n, m = data.n, data.m
    lo, hi = data_ranges(data.states, data.inputs, spec)
    shape = (data.trajectories, data.steps + 1, n + m)
    ranges = [effective_ranges(lo, hi, int(b), spec.guard, spec.dither) for b in bits]
    lo_q = np.array([r[0] for r in ranges]).reshape(len(bits), n + m)
    eps = np.array([r[1] for r in ranges]).reshape(len(bits), n + m)
    sub = 1.0 if spec.dither == "subtractive" else 0.0
    note = (
        ""
        if spec.dither == "subtractive"
        else (
            f"no exact correction with {spec.dither} dither (the error is not independent uniform noise): "
            "the Bernoulli correction is applied nominally"
        )
    )
    T = data.T
    entries = data.T * n + data.T * m + data.trajectories * n
    out: list[list[LiftedMoments]] = []
    for seed in seeds:
        W = draw_dither_units(np.random.default_rng(seed), shape, spec.dither)
        if not isinstance(lifting, MonomialLifting):
            W0 = np.zeros(shape) if W is None else W
            out.append(
                [_rbf_moments(data, lifting, int(b), spec, W0, lo, hi, e, T) for b, e in zip(bits, eps, strict=True)]
            )
            continue
        plan = plan_for(lifting.exponents, m)
        levels = 2.0 ** np.asarray(bits, dtype=float)
        SG, XU, UU, XC, over = lifted_sums(data.states, data.inputs, W, lo_q, eps, levels, sub, plan)
        Bc = bernoulli_shifted(int(plan.Gc.max())) if unbiased else None
        moms = []
        for j in range(len(bits)):
            PP, XP = moments_from_sums(plan, SG[j], XU[j], UU[j], XC[j])
            mom = LiftedMoments(PP, XP, T, eps[j], overload_fraction=float(over[j]) / entries, note=note)
            if Bc is not None:
                UUu = UU[j] - T * np.diag(eps[j, n:] ** 2 / 12.0)
                mom.PPu, mom.XPu = moments_from_sums(plan, SG[j], XU[j], UUu, XC[j], bernoulli_maps(Bc, eps[j, :n]))
            moms.append(mom)
        out.append(moms)
    return out


def _rbf_moments(
    data: Dataset,
    lifting: Lifting,
    b: int,
    spec: QuantizerSpec,
    W: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    eps: np.ndarray,
    T: int,
) -> LiftedMoments:
    """A non-polynomial dictionary: quantize with the engine's quantizer, lift, form the moments (LS only)."""
    n = data.n
    xq = quantize(data.states, lo[:n], hi[:n], b, dither=spec.dither, guard=spec.guard, unit_dither=W[..., :n])
    uq = quantize(data.inputs, lo[n:], hi[n:], b, dither=spec.dither, guard=spec.guard, unit_dither=W[:, :-1, n:])
    Zall = lifting.lift(xq.values)
    mom = _moments(
        Zall[:, :-1].reshape(T, -1), uq.values.reshape(T, -1), Zall[:, 1:].reshape(T, -1), np.asarray(eps, float)
    )
    mom.overload_fraction = float((xq.overload.sum() + uq.overload.sum()) / (xq.overload.size + uq.overload.size))
    mom.note = f"no exact correction for the radial functions of {lifting.spec} (not polynomials): LS only"
    return mom


def edmd(mom: LiftedMoments, C: np.ndarray, estimator: str = "ls") -> KoopmanModel:
    """Fit ``[A_z, B_z]`` from lifted moments.

    Parameters
    ----------
    mom : LiftedMoments
    C : ndarray, shape (n, L)
        The read-back of the lifting.
    estimator : {"ls", "bcls"}
        ``bcls`` uses the de-biased moments; without them (radial functions), or when they are not
        positive definite, LS is used and :attr:`KoopmanModel.note` says why.

    Raises
    ------
    IdentificationError
        Fewer samples than features plus inputs, or a singular Gram matrix.
    """
    check_choice("estimator", estimator, ESTIMATORS)
    L = mom.XP.shape[0]
    p = mom.PP.shape[0]
    if mom.T < p:
        raise IdentificationError(
            f"samples: {mom.T} samples cannot fit {p} unknowns per row ({L} features + {p - L} inputs); "
            "use more runs or steps, or a smaller dictionary"
        )
    if estimator == "bcls":
        if mom.PPu is None or mom.XPu is None:
            A, B = least_squares(mom.PP, mom.XP, L)
            return KoopmanModel(A, B, C, "ls", True, mom.note or "no de-biased moments: plain LS used")
        try:
            A, B = least_squares(mom.PPu, mom.XPu, L)
            return KoopmanModel(A, B, C, "bcls", False, mom.note)
        except IdentificationError:
            A, B = least_squares(mom.PP, mom.XP, L)
            return KoopmanModel(
                A, B, C, "ls", True,
                "bias compensation impossible: the de-biased Gram matrix is not positive definite "
                "(quantization noise comparable to the signal); plain LS used",
            )  # fmt: skip
    A, B = least_squares(mom.PP, mom.XP, L)
    return KoopmanModel(A, B, C, "ls")


def lifted_error(model: KoopmanModel, reference: KoopmanModel) -> tuple[float, float, float]:
    """Relative Frobenius errors ``(err_G, err_A, err_B)`` of ``[A_z, B_z]``, ``A_z``, ``B_z`` against ``reference``."""

    def rel(a: np.ndarray, b: np.ndarray) -> float:
        nb = float(np.linalg.norm(b))
        return float(np.linalg.norm(a - b) / nb) if nb > 0 else float(np.linalg.norm(a - b))

    return rel(model.G, reference.G), rel(model.A, reference.A), rel(model.B, reference.B)


def prediction_error(model: KoopmanModel, lifting: Lifting, held_out: Dataset, horizon: int = 20) -> float:
    """Relative RMS error of the prediction of ``x`` over steps 1..``horizon`` on held-out runs of the true plant
    (cumulative over those steps, not the error ``horizon`` steps ahead alone).

    From ``z_0 = psi(x_0)`` of every run, ``z_{k+1} = A z_k + B u_k`` and ``x^_k = C z_k`` for
    ``k = 1 .. horizon``; returns ``sqrt(sum |x^_k - x_k|^2 / sum |x_k|^2)`` over runs and steps (inf when
    the prediction overflows).
    """
    return prediction_errors([model], lifting, held_out, horizon)[0]


def prediction_errors(
    models: Sequence[KoopmanModel], lifting: Lifting, held_out: Dataset, horizon: int = 20
) -> list[float]:
    """:func:`prediction_error` of several models of one lifting at once (one batched product per step)."""
    if not models:
        return []
    H = min(int(horizon), held_out.steps)
    At = np.stack([mo.A.T for mo in models])  # (models, L, L)
    Bt = np.stack([mo.B.T for mo in models])  # (models, m, L)
    Ct = np.stack([mo.C.T for mo in models])  # (models, L, n)
    z = np.broadcast_to(lifting.lift(held_out.states[:, 0, :]), (len(models),) + (held_out.trajectories, At.shape[1]))
    num = np.zeros(len(models))
    den = 0.0
    with np.errstate(all="ignore"):
        for k in range(H):
            z = z @ At + held_out.inputs[:, k, :] @ Bt
            x = held_out.states[:, k + 1, :]
            num += ((z @ Ct - x) ** 2).sum(axis=(1, 2))
            den += float((x**2).sum())
    return [float(np.sqrt(v / den)) if np.isfinite(v) else float("inf") for v in num]
