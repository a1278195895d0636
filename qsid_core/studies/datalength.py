"""Model error against data length at one word length: finite-data O(eps) vs Theorem 1's O(eps^2) floor.

For each total number of regression samples T, LS and BCLS are run on the data
quantized by ``realizations`` dither realizations, and the relative errors of A
and B are summarised (mean, std) next to Theorem 1's large-data prediction.
LS falls roughly like T^-1/2 until it meets Theorem 1's bias, then levels off;
BCLS (where its hypotheses hold) keeps falling.

Choice of runs x steps (documented in :class:`DataLengthConfig`): runs of the
letter's length (``steps_per_run``, default 1000) while that leaves at least
``min_runs`` (10) runs; shorter runs of ``T // min_runs`` steps below that.
Every length uses a prefix (first runs, first steps) of one simulated data set,
so the data are nested, and **one quantizer range** (that of the largest data
set, or the fixed range) so eps is the same at every length: only T changes.

The what-ifs of a sweep apply as there (:class:`~qsid_core.SweepConfig`'s fields of the same names): the
initial states' amplitude, Gaussian sensor noise on the recorded states (seeded by the data seed; Theorem 1's
``Sigma`` is the noise-free data's and its limit adds ``sigma**2``), BCLS told of that noise or not, and a word
length per channel (states and inputs: ``"b"``, a number or ``"exact"``).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

from ..errors import ConfigError, check_float, check_int
from ..identification.identify import identify, relative_errors
from ..identification.theorem1 import theorem1_prediction
from ..plant.data import Dataset, simulate, with_sensor_noise
from ..plant.lti import LTISystem
from ..plant.systems import get_system
from ..quantization.moments import PreparedData, prepare, quantized_moments
from ..quantization.quantize import MAX_BITS, QuantizerSpec, channel_bits, channel_eps, data_ranges
from ..validate import check_bool
from .cache_keys import system_key
from .config import InputBits, SweepConfig, parse_input_bits, parse_noise, parse_state_bits
from .executors import InlineExecutor, single_threaded_blas
from .summary import Stats, json_clean

__all__ = [
    "DataLengthConfig",
    "DataLengthRow",
    "DataLengthResult",
    "run_datalength",
    "runs_and_steps",
    "DEFAULT_SAMPLES",
    "datalength_key",
]

#: Ten lengths, log-spaced from 1e3 to 1e6 samples.
DEFAULT_SAMPLES = tuple(int(round(v, -2)) if v < 1e5 else int(round(v, -4)) for v in np.logspace(3, 6, 10))


def runs_and_steps(samples: int, steps_per_run: int = 1000, min_runs: int = 10) -> tuple[int, int]:
    """``(runs, steps)`` for ``samples`` regression samples (runs * steps >= samples, close to it).

    Runs of ``steps_per_run`` steps while that gives at least ``min_runs`` runs,
    else ``min_runs`` runs of ``max(1, samples // min_runs)`` steps.
    """
    steps = max(1, min(steps_per_run, samples // min_runs))
    return math.ceil(samples / steps), steps


@dataclass(frozen=True)
class DataLengthConfig:
    """Settings of a data-length study.

    Parameters
    ----------
    system : str or LTISystem
    bits : int, 1..32
        Word length b.
    samples : tuple of int
        Total regression samples T per length (each 20..10^7); sorted, distinct.
    realizations : int, 1..1000
        Dither realizations per length (1 is used without dither: all would be equal).
    quantizer : QuantizerSpec
        Dither, range mode (applied to the largest data set), guard band.
    steps_per_run, min_runs : int
        Run-length rule (see :func:`runs_and_steps`).
    input_amplitude : float
        u ~ U[-A, A].
    data_seed, dither_seed : int
    state_amplitude : float, > 0
        Initial states of the runs x0 ~ U[-a, a]^n (default 1, the letter's).
    noise : float or tuple of float, >= 0
        Gaussian sensor noise on the recorded states, one standard deviation for all or one per state.
    noise_known : bool
        BCLS adds the noise variance to ``D``.
    input_bits, state_bits
        Word length of each input and state (:func:`~qsid_core.studies.parse_input_bits`,
        :func:`~qsid_core.studies.parse_state_bits`); None: ``bits``.
    """

    system: str | LTISystem = "boeing747"
    bits: int = 4
    samples: tuple[int, ...] = DEFAULT_SAMPLES
    realizations: int = 10
    quantizer: QuantizerSpec = field(default_factory=QuantizerSpec)
    steps_per_run: int = 1000
    min_runs: int = 10
    input_amplitude: float = 1.0
    data_seed: int = 0
    dither_seed: int = 1
    state_amplitude: float = 1.0
    noise: tuple[float, ...] = (0.0,)
    noise_known: bool = False
    input_bits: InputBits = None
    state_bits: tuple[int | str, ...] | None = None

    @classmethod
    def from_sweep(cls, sweep: SweepConfig, **changes: Any) -> DataLengthConfig:
        """The study of ``sweep``'s system, data, quantizer and what-ifs: every field the two configs share is
        ``sweep``'s (``bits``, a sweep's list, is not shared: give the study's word length in ``changes``)."""
        shared = {f.name for f in fields(SweepConfig)} - {"bits"}
        taken = {f.name: getattr(sweep, f.name) for f in fields(cls) if f.name in shared}
        return cls(**{**taken, **changes})

    def what_ifs(self) -> dict[str, Any]:
        """The what-if fields (state amplitude, sensor noise, per-channel word lengths) that differ from their
        defaults, as plain data: a study without what-ifs writes the same record as before they existed."""
        plain = DataLengthConfig()
        return {
            name: list(v) if isinstance(v, tuple) else v
            for name in _WHAT_IFS
            for v in [getattr(self, name)]
            if v != getattr(plain, name)
        }

    def __post_init__(self) -> None:
        check_int("bits", self.bits, 1, MAX_BITS)
        try:
            vals = sorted(
                {
                    check_int(
                        "samples",
                        int(v) if isinstance(v, (np.integer, float)) and float(v) == int(v) else v,
                        20,
                        10_000_000,
                    )
                    for v in self.samples
                }
            )
        except TypeError:
            raise ConfigError(f"samples must be a list of integers; got {self.samples!r}") from None
        if not vals:
            raise ConfigError("samples: give at least one data length")
        object.__setattr__(self, "samples", tuple(vals))
        check_int("realizations", self.realizations, 1, 1000)
        check_int("steps per run", self.steps_per_run, 1, 1_000_000)
        check_int("min runs", self.min_runs, 1, 100_000)
        check_float("input amplitude", self.input_amplitude, 0.0, 1e12, lo_open=True)
        check_float("state amplitude", self.state_amplitude, 0.0, 1e12, lo_open=True)
        object.__setattr__(self, "noise", parse_noise(self.noise))
        object.__setattr__(self, "noise_known", check_bool("noise_known", self.noise_known))
        object.__setattr__(self, "input_bits", parse_input_bits(self.input_bits))
        object.__setattr__(self, "state_bits", parse_state_bits(self.state_bits))
        check_int("data seed", self.data_seed, 0)
        check_int("dither seed", self.dither_seed, 0)
        if not isinstance(self.quantizer, QuantizerSpec):
            raise ConfigError("quantizer must be a QuantizerSpec")


def datalength_key(config: DataLengthConfig, system: LTISystem) -> tuple[Any, ...]:
    """The cache key of a data-length study: its name, the system (:func:`~qsid_core.studies.system_key` of
    ``get_system(config.system)``), then every other field of ``config`` in order, generated from its fields (a
    field added to the config is in the key without a line here)."""
    rest = (getattr(config, f.name) for f in fields(config) if f.name != "system")
    return ("datalength", *system_key(system), *rest)


#: The fields a study shares with a sweep's what-ifs (written by :meth:`DataLengthConfig.what_ifs` when set).
_WHAT_IFS = ("state_amplitude", "noise", "noise_known", "input_bits", "state_bits")


@dataclass
class DataLengthRow:
    """One data length: LS and BCLS relative errors (mean, std over realizations) and Theorem 1's floor."""

    samples: int
    trajectories: int
    steps: int
    ls_A: Stats
    ls_B: Stats
    bcls_A: Stats
    bcls_B: Stats
    err_A_theory: float
    err_B_theory: float
    overload_fraction: float
    bcls_fallbacks: int

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = json_clean(
            {
                "samples": self.samples,
                "trajectories": self.trajectories,
                "steps": self.steps,
                "ls": {"err_A": self.ls_A.to_dict(), "err_B": self.ls_B.to_dict()},
                "bcls": {"err_A": self.bcls_A.to_dict(), "err_B": self.bcls_B.to_dict()},
                "err_A_theory": self.err_A_theory,
                "err_B_theory": self.err_B_theory,
                "overload_fraction": self.overload_fraction,
                "bcls_fallbacks": self.bcls_fallbacks,
            }
        )
        return out


@dataclass
class DataLengthResult:
    """A data-length study; ``rows`` holds the lengths finished (all unless ``cancelled``)."""

    config: DataLengthConfig
    system: LTISystem
    eps: np.ndarray
    rows: list[DataLengthRow]
    cancelled: bool = False

    def to_dict(self) -> dict[str, Any]:
        c, q = self.config, self.config.quantizer
        out: dict[str, Any] = json_clean(
            {
                "system": self.system.name,
                "bits": c.bits,
                "config": {
                    "realizations": c.realizations,
                    "dither": q.dither,
                    "range": q.range_mode,
                    "guard": q.guard,
                    "fixed_range": None if q.fixed_range is None else [list(p) for p in q.fixed_range],
                    "steps_per_run": c.steps_per_run,
                    "min_runs": c.min_runs,
                    "input_amplitude": c.input_amplitude,
                    "data_seed": c.data_seed,
                    "dither_seed": c.dither_seed,
                    **c.what_ifs(),
                },
                "eps": self.eps,
                "cancelled": self.cancelled,
                "rows": [r.to_dict() for r in self.rows],
            }
        )
        return out


def _task(
    prep: PreparedData,
    b: int,
    spec: QuantizerSpec,
    seeds: list[np.random.SeedSequence],
    G: np.ndarray,
    n: int,
    channels: tuple[InputBits, tuple[int | str, ...] | None] = (None, None),
    known: np.ndarray | None = None,
) -> np.ndarray:
    """Rows ``[ls_A, ls_B, bcls_A, bcls_B, fallback, overload]`` per realization (picklable for process pools);
    ``channels``: the input and state word lengths, ``known``: sensor noise variance BCLS adds to ``D``."""
    A, B = G[:, :n], G[:, n:]
    out = []
    with single_threaded_blas():
        for ss in seeds:
            rng = np.random.default_rng(ss) if spec.dither != "none" else None
            mo = quantized_moments(prep, [b], spec, rng, input_bits=channels[0], state_bits=channels[1])[0]
            if known is not None:
                mo = replace(mo, D=mo.noise_variance + known)
            row, fb = [], False
            for est in ("ls", "bcls"):
                try:
                    idf = identify(mo, est)
                    row += list(relative_errors(idf.A, idf.B, A, B))
                    fb = fb or idf.fallback
                except ValueError:
                    row += [np.nan, np.nan]
            out.append(row + [float(fb), mo.overload_fraction])
    return np.array(out)


def _prefix(data: Dataset, runs: int, steps: int) -> Dataset:
    return Dataset(data.states[:runs, : steps + 1], data.inputs[:runs, :steps], data.seed, data.input_amplitude)


def _row(
    runs: int,
    steps: int,
    res: np.ndarray,
    prep: PreparedData,
    system: LTISystem,
    eps: np.ndarray,
    dither: str,
    noise: np.ndarray | float = 0.0,
) -> DataLengthRow:
    """The row of one data length from the realizations' results ``res`` (R, 6) and Theorem 1's prediction for
    the data ``prep`` (with sensor noise variance ``noise`` per channel)."""
    n = system.n
    Gp = theorem1_prediction(system.G, prep.exact.PP / prep.exact.T, eps, dither, noise)
    tA, tB = relative_errors(Gp[:, :n], Gp[:, n:], system.A, system.B)
    return DataLengthRow(
        runs * steps,
        runs,
        steps,
        Stats.of(res[:, 0]),
        Stats.of(res[:, 1]),
        Stats.of(res[:, 2]),
        Stats.of(res[:, 3]),
        tA,
        tB,
        float(res[:, 5].mean()),
        int(res[:, 4].sum()),
    )


def run_datalength(
    config: DataLengthConfig,
    executor: Executor | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    should_stop: Callable[[], bool] | threading.Event | None = None,
    tasks: int = 4,
) -> DataLengthResult:
    """Run the study: LS and BCLS errors against data length at ``config.bits``.

    Parameters
    ----------
    config : DataLengthConfig
    executor : Executor, optional
        Runs (length, realization-chunk) tasks (default in-process, lazily, in order).
    progress : callable(done, total, text), optional
        Called after each task.
    should_stop : callable() -> bool or threading.Event, optional
        Checked before each task's result is collected; when true the remaining
        tasks are cancelled and the lengths finished so far are returned with
        ``cancelled=True``.
    tasks : int
        Realization chunks per length.
    """
    stop: Callable[[], bool] = getattr(should_stop, "is_set", None) or should_stop or (lambda: False)  # type: ignore[assignment]  # an Event of any kind, or a callable
    system = get_system(config.system)
    n = system.n
    channels = (config.input_bits, config.state_bits)
    chan = channel_bits(config.bits, n, system.m, *channels)  # a wrong count: one ConfigError before any work
    if len(config.noise) not in (1, n):
        raise ConfigError(f"noise has {len(config.noise)} values; give one for every state or one per state ({n})")
    ex = executor or InlineExecutor()
    plan = [(T, *runs_and_steps(T, config.steps_per_run, config.min_runs)) for T in config.samples]
    J, S = max(r for _, r, _ in plan), max(s for _, _, s in plan)
    master = simulate(system, J, S, config.data_seed, config.input_amplitude, config.state_amplitude)
    noisy = any(v > 0 for v in config.noise)
    # what the sensors record (the noise-free data stay Theorem 1's Sigma), as a sweep's prepared data
    recorded = with_sensor_noise(master, config.noise, config.data_seed) if noisy else master
    variance = np.concatenate([np.broadcast_to(np.square(config.noise), (n,)), np.zeros(system.m)])
    q = config.quantizer
    lo, hi = data_ranges(recorded.states, recorded.inputs, q)
    spec = QuantizerSpec(
        dither=q.dither, range_mode="fixed", guard=q.guard, fixed_range=tuple(zip(lo.tolist(), hi.tolist()))
    )
    eps = channel_eps(lo, hi, chan, q.guard, q.dither)
    known = variance if noisy and config.noise_known else None
    R = 1 if q.dither == "none" else config.realizations
    seeds = np.random.SeedSequence(config.dither_seed).spawn(R)
    size = math.ceil(R / max(1, min(tasks, R)))
    chunks = [seeds[i : i + size] for i in range(0, R, size)]
    futs, preps = [], []
    for _T, runs, steps in plan:
        prep = prepare(_prefix(recorded, runs, steps), spec)
        if noisy:
            prep = replace(prep, exact=prepare(_prefix(master, runs, steps), spec).exact)
        preps.append(prep)
        futs.append([ex.submit(_task, prep, config.bits, spec, ch, system.G, n, channels, known) for ch in chunks])
    rows, done, total, cancelled = [], 0, len(plan) * len(chunks), False
    for (_T, runs, steps), prep, fl in zip(plan, preps, futs):
        parts = []
        for f in fl:
            if stop():
                cancelled = True
                break
            parts.append(f.result())
            done += 1
            if progress:
                progress(done, total, f"T = {runs * steps} ({runs} x {steps})")
        if cancelled:
            break
        rows.append(_row(runs, steps, np.vstack(parts), prep, system, eps, q.dither, variance if noisy else 0.0))
    if cancelled:
        for fl in futs:
            for f in fl:
                f.cancel()
    return DataLengthResult(config, system, np.asarray(eps), rows, cancelled)
