"""Which hypotheses of Theorem 1 and of bias-compensated LS hold for the current settings.

Theorem 1 (large-data regime) needs

1. **dither of known noise variance**: subtractive dither (``x~ = Q(x + w) - w``)
   makes the quantization error uniform with variance ``eps**2/12`` and
   independent of the signal; non-subtractive TPDF dither makes its mean 0 and its
   variance ``eps**2/4`` whatever the signal (see :mod:`qsid_core.quantize`); with
   RPDF dither or none no signal-independent variance exists;
2. **no overload**: ``x + w`` stays inside the quantizer range. Overloaded entries
   have errors larger than ``eps/2`` that depend on the signal. Criterion: at most
   :data:`OVERLOAD_TOLERANCE` (0.1 %) of the quantized entries (states and inputs,
   averaged over realizations) overload;
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
   Large data iff the relative bias of A and of B is at least
   :data:`LARGE_DATA_RATIO` (3) times its fluctuation: the root-mean-square error
   over realizations is then within about 5 % of the bias
   (``sqrt(1 + 1/9) = 1.054``); one realization, or the mean of a few, can still
   differ from it by up to about fluctuation/bias (1/3). Measured on the Boeing
   (200 x 1000, guard band) the predicted fluctuation is within a factor ~2 of
   the spread across dither realizations (it over-estimates at b <= 4). Measured
   at T = 10^6 (1000 x 1000, per-channel range, guard band, 3 realizations): LS
   error of A within 0.2 % of Theorem 1 at b = 2 and 4 (flagged large data),
   B within 0.5 % at b = 2 and 10 % at b = 4; at b = 6 (flagged finite data) B
   is 81 % above the line.

BCLS (``Psi~ Psi~^T - T D``) needs 1 and 2 (the noise variance must be the known
``D``) and, with sensor noise on the states, that noise's variance in ``D`` too
(``noise_known``); not 3 or 4: it removes the bias in finite data as well.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["Assumptions", "assess", "OVERLOAD_TOLERANCE", "STATIONARITY_MARGIN", "LARGE_DATA_RATIO",
           "finite_data_fluctuation"]

#: "No overload" holds when at most this fraction of quantized entries overload.
OVERLOAD_TOLERANCE = 1e-3
#: "Psi Psi^T / T converges" holds when the spectral radius of A is below 1 - this.
STATIONARITY_MARGIN = 1e-6
#: "Large data" holds when Theorem 1's bias is at least this many times the finite-data fluctuation.
LARGE_DATA_RATIO = 3.0


@dataclass(frozen=True)
class Assumptions:
    """Hypotheses of Theorem 1 and of BCLS at one word length (criteria: module docstring).

    Attributes
    ----------
    bits : int
    subtractive_dither : bool
    overload_fraction : float
        Mean over realizations of the fraction of quantized entries that overload.
    overload_tolerance : float
    no_overload : bool
    spectral_radius : float
        ``max |eig(A)|`` of the true system.
    stationary : bool
        ``Psi Psi^T / T`` has a finite limit (spectral radius < 1 - margin).
    bias_A, bias_B : float
        Theorem 1's relative model errors (O(eps**2)).
    fluctuation_A, fluctuation_B : float
        Predicted relative finite-data fluctuation (O(eps / sqrt(T))).
    large_data : bool
        ``bias >= LARGE_DATA_RATIO * fluctuation`` for A and for B.
    theorem1_holds : bool
        All four hypotheses hold: the measured LS error should sit on Theorem 1's line.
    bcls_holds : bool
        Dither of known noise variance and no overload: BCLS removes the bias.
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
    overload_tolerance: float
    no_overload: bool
    spectral_radius: float
    stationary: bool
    bias_A: float
    bias_B: float
    fluctuation_A: float
    fluctuation_B: float
    large_data: bool
    theorem1_holds: bool
    bcls_holds: bool
    notes: tuple = ()
    known_noise: bool = True
    sensor_noise_known: bool = True

    def to_dict(self) -> dict:
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


def assess(ex, b: int) -> Assumptions:
    """The hypotheses at word length ``b`` for an :class:`~qsid_core.experiment.Experiment`."""
    c, sysm = ex.config, ex.system
    n = sysm.n
    moms = ex.moments([b])[b]
    over = float(np.mean([mo.overload_fraction for mo in moms]))
    th = ex.theory(b)
    eps = moms[0].eps
    rad = float(np.abs(np.linalg.eigvals(sysm.A)).max())
    fA, fB = finite_data_fluctuation(sysm.G, ex.prepared.exact.PP, eps)
    # the same denominators as identify.relative_errors (an all-zero A or B is measured against ||[A, B]||)
    nG = float(np.linalg.norm(sysm.G))
    nA, nB = float(np.linalg.norm(sysm.A)), float(np.linalg.norm(sysm.B))
    fA /= nA if nA > 0 else nG
    fB /= nB if nB > 0 else nG
    from .quantize import bcls_reason

    why_not = bcls_reason(c.quantizer.dither)
    dith = not why_not
    no_over = over <= OVERLOAD_TOLERANCE
    stat = rad < 1.0 - STATIONARITY_MARGIN
    large = bool(th.err_A >= LARGE_DATA_RATIO * fA and th.err_B >= LARGE_DATA_RATIO * fB)
    notes = []
    if c.quantizer.dither == "none":
        notes.append("no dither: the quantization error is a deterministic function of the signal, not "
                     "independent noise of variance eps^2/12; every realization is the same")
    elif not dith:
        notes.append(f"{c.quantizer.dither} dither: {why_not}")
    if not no_over:
        notes.append(f"overload: {100 * over:.3g} % of quantized entries left the quantizer range "
                     f"(tolerance {100 * OVERLOAD_TOLERANCE:g} %); their error exceeds eps/2 and depends on the "
                     "signal (use the guard band or a wider range)")
    noisy = any(v > 0 for v in c.noise)
    unknown_noise = noisy and not c.noise_known
    if unknown_noise:
        notes.append("sensor noise on the states is not known to BCLS (noise_known off): BCLS removes only the "
                     "quantization noise's bias, the noise's own bias stays")
    if not stat:
        notes.append(f"A has an eigenvalue on or outside the unit circle (spectral radius {rad:.6g}): "
                     "Psi Psi^T / T has no finite limit, so Theorem 1's T -> inf statement does not apply")
    if not large:
        notes.append(f"finite-data regime: Theorem 1's O(eps^2) bias (A {th.err_A:.3g}, B {th.err_B:.3g}) is not "
                     f"{LARGE_DATA_RATIO:g}x the O(eps) fluctuation of {c.trajectories}x{c.steps} samples "
                     f"(A {fA:.3g}, B {fB:.3g}); the measured LS error lies above Theorem 1's line")
    return Assumptions(
        bits=b, subtractive_dither=c.quantizer.dither == "subtractive", known_noise=dith, overload_fraction=over, overload_tolerance=OVERLOAD_TOLERANCE,
        no_overload=no_over, spectral_radius=rad, stationary=stat, bias_A=float(th.err_A), bias_B=float(th.err_B),
        fluctuation_A=fA, fluctuation_B=fB, large_data=large,
        theorem1_holds=bool(dith and no_over and stat and large),
        bcls_holds=bool(dith and no_over and not unknown_noise), sensor_noise_known=not unknown_noise,
        notes=tuple(notes),
    )
