"""Which hypotheses of Theorem 1 and of bias-compensated LS hold for the current settings.

Theorem 1 (large-data regime) needs

1. **dither of known noise variance**: subtractive dither (``x~ = Q(x + w) - w``)
   makes the quantization error uniform with variance ``eps**2/12`` and
   independent of the signal; non-subtractive TPDF dither makes its mean 0 and its
   variance ``eps**2/4`` whatever the signal (see :mod:`qsid_core.quantization.quantize`); with
   RPDF dither or none no signal-independent variance exists;
2. **no overload in effect**: entries whose ``x`` lies beyond the outermost
   quantizer levels ``[L_lo, L_hi]`` are clipped. With subtractive dither the
   error of such an entry is still ``-w`` (uniform, variance ``eps**2/12``) plus a
   deterministic ``c(x) = clip(x, L_lo, L_hi) - x``: exactly so, since
   ``E_w[Q(x + w) - w] = clip(x, L_lo, L_hi)``. The clipped data's LS limit is
   therefore Theorem 1's formula on the clipped signal,
   ``X_c Psi_c^T (Psi_c Psi_c^T + T D)^-1``; its distance from the unclipped
   prediction (and, for BCLS, ``X_c Psi_c^T (Psi_c Psi_c^T)^-1`` from ``[A, B]``)
   is the predicted **effect of overload** on the estimate (relative, per block).
   Criterion: overload is harmless when that effect is at most
   1/:data:`OVERLOAD_EFFECT_RATIO` (1/3) of the block's finite-data fluctuation
   (below: then it changes the root-mean-square error by at most about 5 %).
   Measured (Boeing, fixed range ±20, no guard band, 200 x 1000): 0.05 % of the
   entries overload at every b; the predicted effect is 1.86e-4 (A) and 7.5e-4
   (B), and the measured LS and BCLS errors level off at 1.86e-4 and 7.5e-4 from
   b = 12 on; at b = 3 the same clipping is 1/24 of the fluctuation (harmless).
   On the letter's Boeing settings (data range, no guard band) it moves B^ by
   6.6e-2 at b = 2 (7x its fluctuation) and A^ by 3e-4 (1/20): A^ stays on
   Theorem 1's line, B^ does not. A fixed share of overloaded entries says
   nothing about this, so there is no such tolerance;
3. **``Psi Psi^T / T`` converges** to a finite positive definite limit. Criterion:
   spectral radius of ``A`` below ``1 -`` :data:`STATIONARITY_MARGIN`. An
   eigenvalue on or outside the unit circle (an integrator such as the dc-motor
   angle) makes the states' second moments grow with the run length, so there is
   no limit (the data set's own Gram matrix is still finite, but depends on the
   run length);
4. **T large** (the large-data regime). Criterion: Theorem 1's O(eps**2) bias
   dominates the O(eps) finite-data fluctuation. The fluctuation is predicted
   from the errors-in-variables LS covariance ``cov(g_i) = s_i**2 (Psi Psi^T)^-1``
   with residual variance ``s_i**2 = eps_i**2/12 + sum_j G_ij**2 eps_j**2/12``, i.e.
   ``f_A = sqrt(sum_i s_i**2 tr([(Psi Psi^T)^-1]_AA)) / ||A||_F`` (and ``f_B`` alike).
   Large data for a block (A or B) iff its relative bias is at least
   :data:`LARGE_DATA_RATIO` (3) times its fluctuation; each block is judged on
   its own (on the letter's Boeing settings A^ is in the large-data regime up to
   b = 6 and B^ only up to b = 3): the root-mean-square error
   over realizations is then within about 5 % of the bias
   (``sqrt(1 + 1/9) = 1.054``); one realization, or the mean of a few, can still
   differ from it by up to about fluctuation/bias (1/3). Measured on the Boeing
   (200 x 1000, guard band) the predicted fluctuation is within a factor ~2 of
   the spread across dither realizations (it over-estimates at b <= 4). Measured
   at T = 10^6 (1000 x 1000, per-channel range, guard band, 3 realizations): LS
   error of A within 0.2 % of Theorem 1 at b = 2 and 4 (flagged large data),
   B within 0.5 % at b = 2 and 10 % at b = 4; at b = 6 (flagged finite data) B
   is 81 % above the line.

Theorem 1 holds for a block when 1 and 3 hold and 2 and 4 hold for that block.
Where a hypothesis formally fails yet the measured mean LS error is within
:data:`FIT_TOLERANCE` (5 %) of the line, the prediction *fits* (``fits_A``,
``fits_B``): the plots keep the line and say exactly that.

BCLS (``Psi~ Psi~^T - T D``) needs 1 and 2 (the noise variance must be the known
``D``) and, with sensor noise on the states, that noise's variance in ``D`` too
(``noise_known``); not 3 or 4: it removes the bias in finite data as well.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..identification.identify import mean_std_of_known
from .clipping import clipping_effect, clips_nothing

if TYPE_CHECKING:
    from ..plant.lti import LTISystem
    from ..quantization.quantize import QuantizerSpec
    from .config import SweepConfig
    from .stage_cache import Staged

__all__ = [
    "Assumptions",
    "assess",
    "OVERLOAD_EFFECT_RATIO",
    "STATIONARITY_MARGIN",
    "LARGE_DATA_RATIO",
    "FIT_TOLERANCE",
    "finite_data_fluctuation",
    "range_words",
]

#: Overload is harmless when its predicted effect is at most 1/this of the finite-data fluctuation.
OVERLOAD_EFFECT_RATIO = 3.0
#: "Psi Psi^T / T converges" holds when the spectral radius of A is below 1 - this.
STATIONARITY_MARGIN = 1e-6
#: "Large data" holds when Theorem 1's bias is at least this many times the finite-data fluctuation.
LARGE_DATA_RATIO = 3.0
#: The prediction "fits" when the measured mean LS error is within this relative distance of the line.
FIT_TOLERANCE = 0.05


@dataclass(frozen=True)
class Assumptions:
    """Hypotheses of Theorem 1 and of BCLS at one word length (criteria: module docstring).

    Attributes
    ----------
    bits : int
    subtractive_dither : bool
    overload_fraction : float
        Mean over realizations of the fraction of quantized entries whose ``x + w`` left the range.
    overload_range : str
        The quantizer range in words ("±20", "the data's min/max per channel, no guard band").
    overload_effect_A, overload_effect_B : float
        Predicted relative change of A^ and B^ caused by the clipped samples.
    no_overload_A, no_overload_B, no_overload : bool
        The effect is at most ``fluctuation / OVERLOAD_EFFECT_RATIO`` (per block; both).
    spectral_radius : float
        ``max |eig(A)|`` of the true system.
    stationary : bool
        ``Psi Psi^T / T`` has a finite limit (spectral radius < 1 - margin).
    bias_A, bias_B : float
        Theorem 1's relative model errors (O(eps**2)).
    fluctuation_A, fluctuation_B : float
        Predicted relative finite-data fluctuation (O(eps / sqrt(T))).
    large_data_A, large_data_B, large_data : bool
        ``bias >= LARGE_DATA_RATIO * fluctuation`` (per block; both).
    theorem1_holds_A, theorem1_holds_B, theorem1_holds : bool
        Every hypothesis holds for the block (both): its LS error should sit on Theorem 1's line.
    ls_err_A, ls_err_B : float
        Measured mean relative LS error over the realizations.
    fits_A, fits_B : bool
        ``|ls_err - bias| <= FIT_TOLERANCE * bias``: the prediction fits the data.
    bcls_holds : bool
        Dither of known noise variance and no overload in effect: BCLS removes the bias.
    notes : tuple of str
        Plain-words reasons for every hypothesis that fails.
    known_noise : bool
        The dither gives a signal-independent error variance (subtractive or tpdf).
    sensor_noise_known : bool
        No sensor noise, or its variance is in BCLS's ``D`` (``noise_known``).
    """

    bits: int
    subtractive_dither: bool
    overload_fraction: float
    overload_range: str
    overload_effect_A: float
    overload_effect_B: float
    no_overload_A: bool
    no_overload_B: bool
    no_overload: bool
    spectral_radius: float
    stationary: bool
    bias_A: float
    bias_B: float
    fluctuation_A: float
    fluctuation_B: float
    large_data_A: bool
    large_data_B: bool
    large_data: bool
    theorem1_holds_A: bool
    theorem1_holds_B: bool
    theorem1_holds: bool
    ls_err_A: float
    ls_err_B: float
    fits_A: bool
    fits_B: bool
    bcls_holds: bool
    notes: tuple[str, ...] = ()
    known_noise: bool = True
    sensor_noise_known: bool = True

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready data (non-finite numbers become None)."""
        d = asdict(self)
        d["notes"] = list(self.notes)
        return {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in d.items()}


def finite_data_fluctuation(G: np.ndarray, PP: np.ndarray, eps: np.ndarray) -> tuple[float, float]:
    """Predicted absolute Frobenius std of the LS error of A and of B from finite data.

    Parameters
    ----------
    G : ndarray, shape (n, n+m)
        True ``[A, B]``.
    PP : ndarray, shape (n+m, n+m)
        ``Psi Psi^T`` (summed over the T samples) of the unquantized data.
    eps : ndarray, shape (n+m,)
        Cell width per channel.

    Returns
    -------
    (f_A, f_B) : float
        ``sqrt(sum_i s_i**2 tr([PP^-1]_blk))`` for the A block and the B block (model units).
    """
    n = G.shape[0]
    v = np.asarray(eps, dtype=float) ** 2 / 12.0
    s2 = float((v[:n] + (G**2) @ v).sum())
    try:
        Pi = np.linalg.inv(PP)
    except np.linalg.LinAlgError:
        return float("inf"), float("inf")
    return float(np.sqrt(s2 * max(np.trace(Pi[:n, :n]), 0.0))), float(np.sqrt(s2 * max(np.trace(Pi[n:, n:]), 0.0)))


def range_words(spec: QuantizerSpec, lo: np.ndarray, hi: np.ndarray) -> str:
    """The quantizer range in words: 'the range ±20 (no guard band)', 'the per-channel data range (min/max)'."""
    guard = "guard band" if spec.guard else "no guard band"
    if np.allclose(lo, lo[0]) and np.allclose(hi, hi[0]):
        a, b = float(lo[0]), float(hi[0])
        return "the range " + (f"±{b:g}" if np.isclose(a, -b) else f"[{a:g}, {b:g}]") + f" ({guard})"
    if spec.range_mode == "per-channel":
        return f"the per-channel data range (min/max, {guard})"
    return f"the {spec.range_mode} range ({guard})"


def _block_norms(sysm: LTISystem) -> tuple[float, float]:
    """The denominators of identify.relative_errors (an all-zero A or B is measured against ||[A, B]||)."""
    nG = float(np.linalg.norm(sysm.G))
    nA, nB = float(np.linalg.norm(sysm.A)), float(np.linalg.norm(sysm.B))
    return (nA if nA > 0 else nG), (nB if nB > 0 else nG)


def _overload_note(a: dict[str, Any]) -> str:
    """Plain words for overload that matters: what clips, how much, and what it does to the estimate."""
    bad = [k for k in "AB" if not a[f"no_overload_{k}"]]
    hat = {"A": "Â", "B": "B̂"}
    head = f"overload: {a['overload_range']} clips {100 * a['overload_fraction']:.2g} % of the samples"
    eff = max(a[f"overload_effect_{k}"] for k in bad)
    if eff >= max(max(a[f"bias_{k}"], a[f"fluctuation_{k}"]) for k in bad):
        return (
            f"{head}; that, not the data length, sets the error floor of {' and '.join(hat[k] for k in bad)} "
            "(predicted " + ", ".join(f"{k} {a[f'overload_effect_{k}']:.3g}" for k in bad) + ")"
        )
    moves = ", ".join(
        f"{hat[k]} by {a[f'overload_effect_{k}']:.2g} "
        f"({a[f'overload_effect_{k}'] / max(a[f'fluctuation_{k}'], 1e-300):.2g}x its finite-data "
        "fluctuation)"
        for k in bad
    )
    return f"{head}; that moves {moves} (harmless below 1/{OVERLOAD_EFFECT_RATIO:g})"


def _notes(a: dict[str, Any], c: SweepConfig) -> list[str]:
    from ..quantization.quantize import bcls_reason

    notes: list[str] = []
    if c.quantizer.dither == "none":
        notes.append(
            "no dither: the quantization error is a deterministic function of the signal, not "
            "independent noise of variance eps^2/12; every realization is the same"
        )
    elif not a["known_noise"]:
        notes.append(f"{c.quantizer.dither} dither: {bcls_reason(c.quantizer.dither)}")
    if not a["sensor_noise_known"]:
        notes.append(
            "sensor noise on the states is not known to BCLS (noise_known off): BCLS removes only the "
            "quantization noise's bias, the noise's own bias stays"
        )
    if not a["no_overload"]:
        notes.append(_overload_note(a))
    if not a["stationary"]:
        notes.append(
            f"A has an eigenvalue on or outside the unit circle (spectral radius {a['spectral_radius']:.6g}): "
            "Psi Psi^T / T has no finite limit, so Theorem 1's T -> inf statement does not apply"
        )
    small = [k for k in "AB" if not a[f"large_data_{k}"]]
    if small:
        parts = ", ".join(f"{k} {a[f'bias_{k}']:.3g} vs {a[f'fluctuation_{k}']:.3g}" for k in small)
        notes.append(
            f"finite-data regime for {' and '.join(small)}: Theorem 1's O(eps^2) bias is not "
            f"{LARGE_DATA_RATIO:g}x the O(eps) fluctuation of {c.trajectories}x{c.steps} samples "
            f"({parts}); the measured LS error lies above Theorem 1's line"
        )
    for k in "AB":
        if a[f"fits_{k}"] and not a[f"theorem1_holds_{k}"]:
            notes.append(
                f"Theorem 1 for {k}: a hypothesis formally fails yet the prediction fits: the mean LS "
                f"error {a[f'ls_err_{k}']:.4g} is within {100 * FIT_TOLERANCE:g} % of the line "
                f"{a[f'bias_{k}']:.4g}"
            )
    return notes


def overload_effect(
    ex: Staged, b: int, matrices: Callable[[], tuple[np.ndarray, np.ndarray]] | None = None
) -> np.ndarray:
    """:func:`clipping_effect` at word length ``b`` for an :class:`~qsid_core.studies.experiment.Experiment`, shape
    (n, n+m); zeros when nothing clips. Needs the data and the quantizer only (no quantized data).

    ``matrices``: returns the data's ``(Psi, X+)`` (:meth:`~qsid_core.plant.data.Dataset.matrices`), e.g. built
    once for several word lengths; called only when the quantizer clips."""
    from ..quantization.quantize import ERROR_VARIANCE, channel_bits, channel_eps, guard_cells

    c, sysm, prep, q = ex.config, ex.system, ex.prepared, ex.config.quantizer
    chan = channel_bits(b, sysm.n, sysm.m, c.input_bits, c.state_bits)
    eps = channel_eps(prep.lo, prep.hi, chan, q.guard, q.dither)  # 0 where a channel is recorded exactly
    cb = np.array([bb if bb is not None else 1 for bb in chan], dtype=float)
    lo_q = np.asarray(prep.lo, dtype=float) - np.array([guard_cells(q.dither, q.guard, int(bb)) for bb in cb]) * eps
    if clips_nothing(ex.data.extremes(), lo_q, eps, cb):  # the usual case: no copy of the data needed
        return np.zeros_like(sysm.G)
    Psi, Xp = matrices() if matrices is not None else ex.data.matrices()
    variance = ERROR_VARIANCE.get(q.dither, 1.0 / 12.0)
    grams = (prep.exact.PP, prep.exact.XP)
    return clipping_effect(sysm.G, Psi, Xp, lo_q, eps, cb, variance, ex.data.extremes(), grams)


def assess(ex: Staged, b: int) -> Assumptions:
    """The hypotheses at word length ``b`` for an :class:`~qsid_core.studies.experiment.Experiment`."""
    from ..quantization.quantize import bcls_reason

    c, sysm = ex.config, ex.system
    n = sysm.n
    q = c.quantizer
    moms = ex.moments([b])[b]
    th = ex.theory(b)
    prep = ex.prepared
    eps = np.asarray(moms[0].eps, dtype=float)  # per channel (0 where a channel is recorded exactly)
    nA, nB = _block_norms(sysm)
    fA, fB = finite_data_fluctuation(sysm.G, prep.exact.PP, eps)
    clip = ex.overload_effect(b)
    ls = ex.identification(b, "ls")
    known = not bcls_reason(q.dither)
    unknown_sensor_noise = any(v > 0 for v in c.noise) and not c.noise_known
    a: dict[str, Any] = dict(
        bits=b,
        subtractive_dither=q.dither == "subtractive",
        known_noise=known,
        sensor_noise_known=not unknown_sensor_noise,
        overload_fraction=float(np.mean([mo.overload_fraction for mo in moms])),
        overload_range=range_words(c.quantizer, prep.lo, prep.hi),
        overload_effect_A=float(np.linalg.norm(clip[:, :n])) / nA,
        overload_effect_B=float(np.linalg.norm(clip[:, n:])) / nB,
        spectral_radius=float(np.abs(np.linalg.eigvals(sysm.A)).max()),
        bias_A=float(th.err_A),
        bias_B=float(th.err_B),
        fluctuation_A=fA / nA,
        fluctuation_B=fB / nB,
        ls_err_A=mean_std_of_known(ls.err_A)[0],
        ls_err_B=mean_std_of_known(ls.err_B)[0],
    )
    a["stationary"] = a["spectral_radius"] < 1.0 - STATIONARITY_MARGIN
    for k in "AB":
        a[f"no_overload_{k}"] = bool(a[f"overload_effect_{k}"] * OVERLOAD_EFFECT_RATIO <= a[f"fluctuation_{k}"])
        a[f"large_data_{k}"] = bool(a[f"bias_{k}"] >= LARGE_DATA_RATIO * a[f"fluctuation_{k}"])
        a[f"theorem1_holds_{k}"] = bool(
            a["known_noise"] and a["stationary"] and a[f"no_overload_{k}"] and a[f"large_data_{k}"]
        )
        bias, err = a[f"bias_{k}"], a[f"ls_err_{k}"]
        a[f"fits_{k}"] = bool(np.isfinite(err) and abs(err - bias) <= FIT_TOLERANCE * bias)
    a["no_overload"] = a["no_overload_A"] and a["no_overload_B"]
    a["large_data"] = a["large_data_A"] and a["large_data_B"]
    a["theorem1_holds"] = a["theorem1_holds_A"] and a["theorem1_holds_B"]
    a["bcls_holds"] = bool(a["known_noise"] and a["no_overload"] and a["sensor_noise_known"])
    return Assumptions(**a, notes=tuple(_notes(a, c)))
