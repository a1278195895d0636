"""The quantizer seen on one signal: with subtractive dither and without.

:func:`quantizer_demo` quantizes one channel twice at word length b, once with
subtractive dither (``Q(x + w) - w``) and once plainly (``Q(x)``), and returns a
short window of the signal and both reconstructions, the two error histograms
against the uniform density ``1/eps`` on ``[-eps/2, eps/2]``, the measured error
variances next to ``eps**2/12``, the overload fractions and the correlation of the
error with the signal. :func:`channel_demo` does this for one state or input
channel of an :class:`~qsid_core.studies.experiment.Experiment`'s training data, with its
quantizer range.

What it shows: with dither and no overload the error is uniform, of variance
``eps**2/12`` (within sampling error ``eps**2 / sqrt(180 N)``: the variance of
``e**2`` for e uniform on ``[-eps/2, eps/2]`` is ``eps**4/180``) and uncorrelated
with the signal. Without dither the error is a deterministic function of the
signal; for a coarse quantizer or a slowly varying signal it is correlated with it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, TypedDict

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ConfigError, check_float, check_int
from ..plant.data import Dataset
from ..plant.lti import LTISystem
from ..validate import MAX_MAGNITUDE
from .moments import PreparedData
from .quantize import MAX_BITS, QuantizerSpec, effective_ranges, quantize

__all__ = ["QuantizerDemo", "quantizer_demo", "channel_demo", "SCATTER_POINTS", "CELL_BINS"]


@dataclass
class QuantizerDemo:
    """One signal quantized with and without subtractive dither.

    Attributes
    ----------
    bits : int
    eps : float
        Cell width (signal units).
    lo_q, hi_q : float
        The quantizer's actual range (guard band included).
    samples : int
        N, samples the statistics use.
    t : ndarray, shape (W,)
        Sample indices of the window.
    signal, dithered, plain : ndarray, shape (W,)
        ``x``, ``Q(x + w) - w`` and ``Q(x)`` over the window.
    error_dithered, error_plain : ndarray, shape (W,)
        ``x - x~`` over the window.
    hist_edges : ndarray, shape (bins + 1,)
        Bin edges on ``[-eps/2, eps/2]``.
    hist_dithered, hist_plain : ndarray, shape (bins,)
        Error densities (1 / signal units) over all N samples; mass outside
        ``[-eps/2, eps/2]`` (overload) is in ``outside_*``, not in the bins.
    uniform_density : float
        ``1 / eps``, the density of the ideal error.
    var_dithered, var_plain, var_theory : float
        Measured error variances and ``eps**2 / 12`` (signal units squared).
    var_sampling_std : float
        ``eps**2 / sqrt(180 N)``: standard error of the measured variance of an ideal error.
    mean_dithered, mean_plain : float
    corr_dithered, corr_plain : float
        Correlation of the error with the signal.
    cell_dependence_dithered, cell_dependence_plain : float
        Share of the error's variance fixed by where ``x`` sits in its cell (correlation
        ratio of the error over 16 bins of ``frac((x - lo_q) / eps)``): 1 for a deterministic
        sawtooth of ``x``, about ``16 / N`` for an error independent of ``x``.
    scatter_x, scatter_dithered, scatter_plain : ndarray, shape (S,)
        Up to :data:`SCATTER_POINTS` samples spread over all N: ``x`` and both errors.
        Correlation coefficient of error and signal (NaN for a constant signal).
    overload_dithered, overload_plain : float
        Fraction of samples whose quantizer input left the range.
    outside_dithered, outside_plain : float
        Fraction of errors outside ``[-eps/2, eps/2]``.
    label : str
        The channel's name (``"x1"``, ``"u2"``, ...) or ``""``.
    """

    bits: int
    eps: float
    lo_q: float
    hi_q: float
    samples: int
    t: np.ndarray
    signal: np.ndarray
    dithered: np.ndarray
    plain: np.ndarray
    error_dithered: np.ndarray
    error_plain: np.ndarray
    hist_edges: np.ndarray
    hist_dithered: np.ndarray
    hist_plain: np.ndarray
    uniform_density: float
    var_dithered: float
    var_plain: float
    var_theory: float
    var_sampling_std: float
    mean_dithered: float
    mean_plain: float
    corr_dithered: float
    corr_plain: float
    cell_dependence_dithered: float
    cell_dependence_plain: float
    scatter_x: np.ndarray
    scatter_dithered: np.ndarray
    scatter_plain: np.ndarray
    overload_dithered: float
    overload_plain: float
    outside_dithered: float
    outside_plain: float
    label: str = ""

    @property
    def var_z_dithered(self) -> float:
        """``(var_dithered - eps**2/12) / var_sampling_std``: deviation in standard errors."""
        return float((self.var_dithered - self.var_theory) / self.var_sampling_std)


#: Samples of (x, error) the error-vs-signal plot draws.
SCATTER_POINTS = 1500
#: Bins of the position in the cell for :attr:`QuantizerDemo.cell_dependence_dithered`.
CELL_BINS = 16


def _cell_dependence(e: np.ndarray, pos: np.ndarray) -> float:
    """Correlation ratio: between-bin variance of ``e`` over ``CELL_BINS`` bins of ``pos`` in [0, 1), / var(e)."""
    v = e.var()
    if v == 0:
        return float("nan")
    k = np.clip((pos * CELL_BINS).astype(int), 0, CELL_BINS - 1)
    cnt = np.bincount(k, minlength=CELL_BINS)
    mean = np.bincount(k, weights=e, minlength=CELL_BINS) / np.maximum(cnt, 1)
    return float(np.sum(cnt * (mean - e.mean()) ** 2) / (e.size * v))


def _corr(e: np.ndarray, x: np.ndarray) -> float:
    se, sx = e.std(), x.std()
    if se == 0 or sx == 0:
        return float("nan")
    return float(np.mean((e - e.mean()) * (x - x.mean())) / (se * sx))


class _ErrorStats(TypedDict):
    var_dithered: float
    var_plain: float
    var_theory: float
    var_sampling_std: float
    mean_dithered: float
    mean_plain: float
    corr_dithered: float
    corr_plain: float
    cell_dependence_dithered: float
    cell_dependence_plain: float
    outside_dithered: float
    outside_plain: float


def _error_stats(x: np.ndarray, ed: np.ndarray, ep: np.ndarray, lo_q: float, eps: float) -> _ErrorStats:
    """The statistics of the errors with dither ``ed`` and without ``ep`` (shape (N,)) of signal ``x``."""
    tol = 1e-12 * max(eps, 1.0)
    pos = np.mod((x - lo_q) / eps, 1.0)
    return _ErrorStats(
        var_dithered=float(ed.var()),
        var_plain=float(ep.var()),
        var_theory=eps**2 / 12.0,
        var_sampling_std=float(eps**2 / np.sqrt(180.0 * x.size)),
        mean_dithered=float(ed.mean()),
        mean_plain=float(ep.mean()),
        corr_dithered=_corr(ed, x),
        corr_plain=_corr(ep, x),
        cell_dependence_dithered=_cell_dependence(ed, pos),
        cell_dependence_plain=_cell_dependence(ep, pos),
        outside_dithered=float(np.mean(np.abs(ed) > eps / 2 + tol)),
        outside_plain=float(np.mean(np.abs(ep) > eps / 2 + tol)),
    )


def _checked_signal(signal: ArrayLike, lo: float, hi: float) -> tuple[np.ndarray, float, float]:
    """``(x, lo, hi)``: the signal flattened, shape (N,), and the range, checked (finite, within the engine's
    magnitude limit, at least 2 samples)."""
    x = np.asarray(signal, dtype=float).ravel()
    if x.size < 2 or not np.all(np.isfinite(x)):
        raise ConfigError("the quantizer demo needs a finite signal of at least 2 samples")
    lo = check_float("lo", lo, -MAX_MAGNITUDE, MAX_MAGNITUDE)
    hi = check_float("hi", hi, -MAX_MAGNITUDE, MAX_MAGNITUDE)
    if np.abs(x).max() > MAX_MAGNITUDE:
        raise ConfigError(
            f"the quantizer demo needs the signal within ±{MAX_MAGNITUDE:g} (its error variance "
            "eps²/12 must stay a number)"
        )
    return x, lo, hi


def quantizer_demo(
    signal: ArrayLike,
    lo: float,
    hi: float,
    bits: int,
    *,
    guard: bool = True,
    window: int = 200,
    start: int = 0,
    bins: int = 30,
    seed: int | None = 0,
    label: str = "",
) -> QuantizerDemo:
    """Quantize a 1-D signal with and without subtractive dither and compare the errors.

    Parameters
    ----------
    signal : array_like, shape (N,)
        The signal (any units); all N samples feed the statistics.
    lo, hi : float
        Quantizer range, ``hi > lo`` (before the guard band).
    bits : int, 1..32
    guard : bool
        Guard band (see :mod:`qsid_core.quantization.quantize`).
    window : int, >= 1
        Samples returned for the time plot (from ``start``; clipped to N).
    start : int, >= 0
    bins : int, 2..1000
        Histogram bins on ``[-eps/2, eps/2]``.
    seed : int or None
        Seed of the dither.

    Raises
    ------
    ConfigError
        Empty or non-finite signal, bad range, bits, window, start or bins.
    """
    x, lo, hi = _checked_signal(signal, lo, hi)
    bits = check_int("bits", bits, 1, MAX_BITS)
    window = check_int("window", window, 1)
    start = check_int("start", start, 0, x.size - 1)
    bins = check_int("bins", bins, 2, 1000)
    rng = np.random.default_rng(seed)
    qd = quantize(x, lo, hi, bits, dither="subtractive", guard=guard, rng=rng)
    qp = quantize(x, lo, hi, bits, dither="none", guard=guard)
    lo_arr, eps_arr = effective_ranges(np.array([lo], dtype=float), np.array([hi], dtype=float), bits, guard)
    lo_q, eps = float(lo_arr[0]), float(eps_arr[0])
    ed, ep = x - qd.values, x - qp.values
    edges = np.linspace(-eps / 2, eps / 2, bins + 1)
    N = x.size
    hd = np.histogram(ed, bins=edges)[0] / (N * np.diff(edges))
    hp = np.histogram(ep, bins=edges)[0] / (N * np.diff(edges))
    sl = slice(start, min(start + window, N))
    pick = np.unique(np.linspace(0, N - 1, min(N, SCATTER_POINTS)).astype(int))
    return QuantizerDemo(
        bits=bits,
        eps=eps,
        lo_q=lo_q,
        hi_q=float(lo_q + 2.0**bits * eps),
        samples=N,
        t=np.arange(N)[sl],
        signal=x[sl].copy(),
        dithered=qd.values[sl],
        plain=qp.values[sl],
        error_dithered=ed[sl],
        error_plain=ep[sl],
        hist_edges=edges,
        hist_dithered=hd,
        hist_plain=hp,
        uniform_density=1.0 / eps,
        **_error_stats(x, ed, ep, lo_q, eps),
        scatter_x=x[pick],
        scatter_dithered=ed[pick],
        scatter_plain=ep[pick],
        overload_dithered=qd.overload_fraction,
        overload_plain=qp.overload_fraction,
        label=label,
    )


class _Recorded(Protocol):
    """What :func:`channel_demo` reads of an experiment (:class:`~qsid_core.studies.experiment.Experiment`)."""

    @property
    def system(self) -> LTISystem: ...
    @property
    def data(self) -> Dataset: ...
    @property
    def prepared(self) -> PreparedData: ...
    @property
    def config(self) -> _WithQuantizer: ...


class _WithQuantizer(Protocol):
    @property
    def quantizer(self) -> QuantizerSpec: ...


def channel_demo(
    ex: _Recorded,
    channel: int,
    bits: int,
    *,
    window: int = 200,
    max_samples: int = 100_000,
    bins: int = 30,
    seed: int | None = 0,
) -> QuantizerDemo:
    """:func:`quantizer_demo` for one channel of an experiment's training data, with its quantizer range.

    Parameters
    ----------
    ex : Experiment
    channel : int, 0..n+m-1
        States first (``x1..xn``), then inputs (``u1..um``).
    bits : int
    window, bins, seed
        As in :func:`quantizer_demo`.
    max_samples : int
        The statistics use the first ``max_samples`` samples of the channel (run after run).
    """
    n, m = ex.system.n, ex.system.m
    channel = check_int("channel", channel, 0, n + m - 1)
    max_samples = check_int("max samples", max_samples, 2)
    data, prep = ex.data, ex.prepared
    if channel < n:
        sig, label = data.states[:, :-1, channel].ravel(), f"x{channel + 1}"
    else:
        sig, label = data.inputs[:, :, channel - n].ravel(), f"u{channel - n + 1}"
    return quantizer_demo(
        sig[:max_samples],
        float(prep.lo[channel]),
        float(prep.hi[channel]),
        bits,
        guard=ex.config.quantizer.guard,
        window=window,
        bins=bins,
        seed=seed,
        label=label,
    )
