"""One study of a plant over the word length, for every front end: the current b first, then the rest.

:class:`Study` takes a frozen configuration — :class:`~qsid_core.studies.config.SweepConfig` for a linear plant,
:class:`~qsid_core.studies.config.KoopmanConfig` for a nonlinear one; the plant's kind is the config's, not
a second code path for the caller — with an executor and a cache. :meth:`Study.frames` yields what a front end
shows as it becomes known (:class:`StudyFrame`: the current word length in full first, then the others), until
done or until its :class:`CancelToken` is cancelled; :meth:`Study.run` computes the whole sweep at once (the
CLI's result). Its stages and cache keys are the experiments' (:class:`~qsid_core.studies.experiment.Experiment`,
:class:`~qsid_core.studies.study_nonlinear.KoopmanExperiment`); two studies given the same cache share every
stage they have in common, in flight included (:class:`~qsid_core.studies.flights.Flights`).

Examples
--------
>>> from qsid_core import SweepConfig
>>> from qsid_core.studies import Study
>>> study = Study(SweepConfig(system="dc-motor", bits=(4, 8), realizations=2, trajectories=20, steps=100))
>>> [(f.stage, f.done, f.total) for f in study.frames(bits=8)]
[('current', 1, 2), ('curves', 2, 2)]
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator, Mapping, MutableMapping
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..control import ClosedLoops, KoopmanLoops
from ..errors import ConfigError
from .config import KoopmanConfig, SweepConfig
from .experiment import Experiment
from .stage_results import BitsIdentification, KoopmanModels, TheoryAtBits
from .study_budget import Bandwidth, bandwidth, bandwidth_key
from .study_linear import linear_frames, task_count
from .study_nonlinear import KoopmanExperiment, nonlinear_frames
from .sweep import KoopmanResult, run_sweep
from .sweep_result import SweepResult

__all__ = ["CancelToken", "LinearAtBits", "NonlinearAtBits", "Study", "StudyFrame"]

Progress = Callable[[int, int, str], None]


class CancelToken:
    """Tells a study to stop: :meth:`cancel`, or a ``check`` callable that says so (e.g. "newer settings arrived").

    A cancelled study's :meth:`Study.frames` ends at its next check, between word lengths (about a second);
    work already handed to an executor is the executor's to abandon.
    """

    def __init__(self, check: Callable[[], bool] | None = None) -> None:
        self._event = threading.Event()
        self._check = check

    def cancel(self) -> None:
        self._event.set()

    @property
    def cancelled(self) -> bool:
        return self._event.is_set() or (self._check is not None and bool(self._check()))


@dataclass(frozen=True)
class LinearAtBits:
    """A linear plant's results at the current word length, per estimator (``"ls"``, ``"bcls"``)."""

    idents: Mapping[str, BitsIdentification]
    theory: TheoryAtBits
    loops: Mapping[str, ClosedLoops]
    true_loop: ClosedLoops | None
    x0: NDArray[np.float64]


@dataclass(frozen=True)
class NonlinearAtBits:
    """A nonlinear plant's results at the current word length, per estimator, with the unquantized reference."""

    models: Mapping[str, KoopmanModels]
    loops: Mapping[str, KoopmanLoops | None]
    reference: Any
    reference_error: float
    reference_loop: KoopmanLoops | None
    flow: NDArray[np.float64]
    x0: NDArray[np.float64]
    horizon: int
    features: int
    data_report: str


@dataclass(frozen=True)
class StudyFrame:
    """What a study knows at one moment.

    Attributes
    ----------
    kind : {"linear", "nonlinear"}
    stage : {"current", "models", "curves", "budget"}
        ``"current"``: the current b in full; ``"models"`` (nonlinear): every b's models, loops still running;
        ``"curves"``: more word lengths complete; ``"budget"``: the last, once the study's budget study is done
        (only for a study given a budget).
    bits : int
        The current word length.
    estimators : tuple of str
    rows : dict estimator -> {b: row dict}
        The summary rows computed so far (a copy: the study goes on filling its own).
    done, total : int
        Word lengths complete, of all.
    at_bits : LinearAtBits or NonlinearAtBits
        Everything at the current b.
    elapsed : float
        Seconds since :meth:`Study.frames` was called.
    timings : dict
        Seconds from that call to the end of each stage seen so far.
    experiment : Experiment or KoopmanExperiment
        The staged computation behind the frame (its cache holds every b computed so far).
    budget : Bandwidth or None
        The budget study (:mod:`~qsid_core.studies.study_budget`) in the ``"budget"`` frame, else None.
    """

    kind: str
    stage: str
    bits: int
    estimators: tuple[str, ...]
    rows: dict[str, dict[int, dict[str, Any]]]
    done: int
    total: int
    at_bits: LinearAtBits | NonlinearAtBits
    elapsed: float
    timings: dict[str, float] = field(default_factory=dict)
    experiment: Experiment | KoopmanExperiment | None = None
    budget: Bandwidth | None = None

    @property
    def complete(self) -> bool:
        return self.done >= self.total


class Study:
    """A word-length study of one configuration (linear or nonlinear), computed on ``executor`` with ``cache``.

    Parameters
    ----------
    config : SweepConfig or KoopmanConfig
    executor : Executor, optional
        Where independent tasks run (default: in this process).
    cache : mutable mapping, optional
        Stage results; a shared one (the dashboard's) lets studies of other settings reuse what they share.
    workers : int
        The executor's workers (tasks are sized for them; 0 or no executor: none).
    estimators : tuple of str, optional
        The estimators computed (default: the config's).
    tasks : int, optional
        Chunks a linear plant's realizations are split into (default: sized for ``workers``, tasks of a
        fraction of a second, so that abandoned work never holds the executor long).
    budget : float, optional
        A budget of bits: :meth:`frames` ends with a ``"budget"`` frame holding the budget study of this
        configuration (:func:`~qsid_core.studies.study_budget.bandwidth`, judged on the last estimator).
    bits_per_sample : int, optional
        With a budget: its study also holds the per-channel allocation of that many bits per sample.
    """

    def __init__(
        self,
        config: SweepConfig | KoopmanConfig,
        executor: Executor | None = None,
        cache: MutableMapping[Any, Any] | None = None,
        workers: int = 0,
        estimators: tuple[str, ...] | None = None,
        tasks: int | None = None,
        budget: float | None = None,
        bits_per_sample: int | None = None,
    ) -> None:
        if not isinstance(config, (SweepConfig, KoopmanConfig)):
            raise ConfigError(f"config: a SweepConfig or a KoopmanConfig, not {type(config).__name__}")
        self.config = config
        self.executor = executor
        self.workers = max(0, int(workers)) if executor is not None else 0
        self.estimators = tuple(estimators) if estimators else (config.estimator,)
        self.budget = budget
        self.bits_per_sample = bits_per_sample
        self.cache = cache
        self.experiment: Experiment | KoopmanExperiment
        if isinstance(config, SweepConfig):
            samples = config.trajectories * config.steps
            if tasks is None:
                tasks = task_count(samples, config.realizations, 1, self.workers) if self.workers else 1
            self.experiment = Experiment(config, executor=executor, tasks=tasks, cache=cache)
        else:
            self.experiment = KoopmanExperiment(config, cache)

    @property
    def kind(self) -> str:
        """``"linear"`` or ``"nonlinear"`` (the config's plant)."""
        return "nonlinear" if isinstance(self.config, KoopmanConfig) else "linear"

    def frames(
        self,
        bits: int | None = None,
        cancel: CancelToken | None = None,
        progress: Progress | None = None,
        min_interval: float = 0.3,
        chunk: int | None = None,
        memo: MutableMapping[Any, Any] | None = None,
    ) -> Iterator[StudyFrame]:
        """The frames of the study with ``bits`` (default: the config's largest) as the current word length.

        ``progress(done, total, text)`` is called before each stage; a frame comes at most every
        ``min_interval`` s (and at the end); ``chunk``: word lengths quantized per pass (linear; default all
        the others in one pass); ``memo``: one caller's rows from earlier studies, reused when built from the
        very same results (used by one thread at a time).
        """
        b = int(bits) if bits is not None else max(self.config.bits)
        if b not in self.config.bits:
            raise ConfigError(f"bits: {b} is not among the study's word lengths {tuple(self.config.bits)}")
        stop = (lambda: cancel.cancelled) if cancel is not None else (lambda: False)
        total, t0, timings = len(self.config.bits), time.perf_counter(), {}
        if progress:
            progress(0, total, f"computing b={b} (1/{total})")
        ex = self.experiment
        if isinstance(ex, Experiment):
            steps = linear_frames(
                ex, self.estimators, b, stop, self.workers, chunk or max(1, total - 1), min_interval, progress, memo
            )
        else:
            steps = nonlinear_frames(ex, self.estimators, b, stop, self.executor, self.workers, min_interval, progress)
        last = None
        for stage, rows, done in steps:
            timings[stage] = time.perf_counter() - t0
            at = self._at_bits(b)
            copy = {e: dict(r) for e, r in rows.items()}
            last = StudyFrame(
                self.kind, stage, b, self.estimators, copy, done, total, at, timings[stage], dict(timings), ex
            )
            yield last
        if self.budget is None or last is None or not last.complete or (cancel is not None and cancel.cancelled):
            return
        if progress:
            progress(total, total, f"budget of {self.budget:g} bits")
        check = None if cancel is None else (lambda: cancel.cancelled)
        found = self._bandwidth(self.budget, check)
        if found is not None:
            timings["budget"] = time.perf_counter() - t0
            yield replace(last, stage="budget", elapsed=timings["budget"], timings=dict(timings), budget=found)

    def _bandwidth(self, total_bits: float, check: Callable[[], bool] | None) -> Bandwidth | None:
        """The budget study of this configuration, from the cache when another study of it computed it."""
        key = bandwidth_key(self.config, total_bits, self.estimators[-1], self.bits_per_sample)
        if self.cache is not None:
            try:
                found: Bandwidth | None = self.cache[key]
                return found
            except KeyError:
                pass
        found = bandwidth(self.config, total_bits, self.estimators[-1], self.executor, check, self.bits_per_sample)
        if found is not None and self.cache is not None:
            self.cache[key] = found
        return found

    def _at_bits(self, b: int) -> LinearAtBits | NonlinearAtBits:
        ex, ests = self.experiment, self.estimators
        mpc = self.config.mpc
        x0 = np.asarray(mpc.x0 if mpc is not None and mpc.x0 is not None else ex.system.x0, dtype=float)
        if isinstance(ex, Experiment):
            loops = {e: ex.closed_loops(b, e) for e in ests} if mpc is not None else {}
            true_loop = ex.true_model_loop() if mpc is not None else None
            return LinearAtBits({e: ex.identification(b, e) for e in ests}, ex.theory(b), loops, true_loop, x0)
        ref, ref_err = ex.reference()
        return NonlinearAtBits(
            models={e: ex.models(b, e) for e in ests},
            loops={e: ex.cached_loops(b, e) for e in ests},
            reference=ref,
            reference_error=ref_err,
            reference_loop=ex.reference_loop(),
            flow=ex.free_flow(),
            x0=x0,
            horizon=ex.horizon,
            features=ex.lifting.L,
            data_report=ex.data()[0].report,
        )

    def run(self, progress: Callable[[int, int, str], None] | None = None) -> SweepResult | KoopmanResult:
        """The whole sweep at once: a :class:`SweepResult` (linear) or a :class:`KoopmanResult` (nonlinear)."""
        ex, cfg = self.experiment, self.config
        if isinstance(ex, KoopmanExperiment):
            assert isinstance(cfg, KoopmanConfig)
            return run_sweep(cfg, experiment=ex)  # the rows from this study's stages and cache
        assert isinstance(cfg, SweepConfig)
        return run_sweep(cfg, self.executor, progress, experiment=ex, tasks=ex.tasks)
