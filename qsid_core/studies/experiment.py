"""Sweeps over the word length b: identification, theory and MPC, with dither realizations.

For each b, ``realizations`` independent dither realizations quantize the *same*
unquantized data. Realization ``r`` draws its dither from stream ``r`` of
``SeedSequence(dither_seed).spawn(realizations)``, and the same unit draws are
reused for every b (common random numbers: smooth curves, fair comparison
between word lengths).

Independent work is mapped through a :class:`concurrent.futures.Executor`
(default: in-process), so a ``ProcessPoolExecutor`` or a dask.distributed
client's executor can run big sweeps.

Stages are separate so front ends can cache them: :class:`Experiment` keeps the
data, the normalised data and the identified models, and recomputes only what
a change of settings touches. The stages live by responsibility beside it:
``stage_cache`` (where results are kept and every cache key), ``identification_stage``,
``theory_stage`` and ``loop_stages``; this class is their one front.
"""

from __future__ import annotations

from collections.abc import Callable, MutableMapping, Sequence
from concurrent.futures import Executor
from dataclasses import replace
from typing import TYPE_CHECKING, cast

import numpy as np
from numpy.typing import NDArray

from ..control.closed_loop import run_closed_loops
from ..control.loop_results import ClosedLoops
from ..control.realized_bound import RealizedBounds
from ..errors import ConfigError, check_choice, check_int
from ..identification.identify import ESTIMATORS
from ..plant.data import Dataset, simulate, with_sensor_noise
from ..plant.systems import get_system
from ..quantization.moments import Moments, PreparedData, exact_moments, prepare
from .config import SweepConfig, parse_bits
from .config_checks import check_run_args
from .executors import InlineExecutor
from .identification_stage import Progress, compute_moments, identify_at
from .loop_stages import FeedbackRange, feedback_range, loop_args, loops_task, mpc_of, true_loop_args
from .stage_cache import Key, StageCache, StageKeys
from .stage_results import BitsIdentification, TheoryAtBits
from .theory_stage import realized_bound_at, theory_at

if TYPE_CHECKING:
    from .assumptions import Assumptions

__all__ = ["Experiment", "Progress"]


class Experiment:
    """Staged, cached computation for one system and data set.

    Parameters
    ----------
    config : SweepConfig
    executor : concurrent.futures.Executor, optional
        Runs independent tasks (default: :class:`InlineExecutor`). If it has a
        ``share(obj)`` method, the data every task needs is passed through it
        once (a cluster sends it once per worker, not with every task).
    tasks : int
        Number of chunks the realizations are split into for the executor.
    cache : MutableMapping, optional
        Where stage results are kept (default: a private dict). Pass one shared,
        bounded mapping to let several experiments (browser tabs) share results.

    Attributes
    ----------
    keys : StageKeys
        The cache key of every stage (:mod:`qsid_core.studies.stage_cache`).
    cache : StageCache
        The stage results, in ``cache.mapping``.

    Notes
    -----
    Every expensive product is cached by the settings it depends on:
    the data by (trajectories, steps, data seed, input amplitude); the normalised data by the
    quantizer range; moments by (b, dither, dither seed, realizations); models by
    the estimator. :meth:`with_config` returns an experiment for new settings
    that shares every cache entry still valid.
    """

    def __init__(
        self,
        config: SweepConfig,
        executor: Executor | None = None,
        tasks: int = 4,
        cache: MutableMapping[Key, object] | None = None,
    ) -> None:
        check_run_args(config, SweepConfig, executor, None)
        self.config = config
        self.system = get_system(config.system)
        self.executor: Executor = executor or InlineExecutor()
        self.tasks = check_int("tasks", tasks, 1, 1024)
        # keys start with the system's matrices, so one mapping can serve many experiments
        self.cache = StageCache(cache)
        self.keys = StageKeys(config, self.system)

    def with_config(self, config: SweepConfig) -> Experiment:
        """An experiment for ``config`` that reuses this one's still-valid cache entries."""
        return Experiment(config, self.executor, self.tasks, self.cache.mapping)

    # ----- data ----------------------------------------------------------------------------
    def noise_variance(self) -> NDArray[np.float64]:
        """Sensor noise variance per channel of ``Psi``, shape (n + m,) (0 for the inputs)."""
        n, m = self.system.n, self.system.m
        s = np.asarray(self.config.noise, dtype=float)
        if s.size not in (1, n):
            raise ConfigError(f"noise has {s.size} values; give one for every state or one per state ({n})")
        return np.concatenate([np.broadcast_to(s**2, (n,)), np.zeros(m)])

    @property
    def data(self) -> Dataset:
        """The unquantized data set (simulated once)."""
        c = self.config
        return self.cache.memo(
            self.keys.data(),
            lambda: simulate(self.system, c.trajectories, c.steps, c.data_seed, c.input_amplitude, c.state_amplitude),
        )

    @property
    def prepared(self) -> PreparedData:
        """The recorded data (with sensor noise, if any) normalised to the quantizer ranges.

        Its ``exact`` moments are those of the noise-free data (Theorem 1's ``Sigma``).
        """
        return self.cache.memo(self.keys.prepared(), self._prepare)

    def _prepare(self) -> PreparedData:
        c = self.config
        if any(v > 0 for v in c.noise):
            self.noise_variance()  # wrong number of values: one clear error
            rec = with_sensor_noise(self.data, c.noise, c.data_seed)
            return replace(prepare(rec, c.quantizer), exact=exact_moments(self.data))
        return prepare(self.data, c.quantizer)

    @property
    def Sigma(self) -> NDArray[np.float64]:
        """``Psi_uqz Psi_uqz^T / T`` of the unquantized data, shape (n+m, n+m)."""
        ex = self.prepared.exact
        return ex.PP / ex.T

    # ----- identification ------------------------------------------------------------------
    def moments(self, bits: str | int | Sequence[int], progress: Progress | None = None) -> dict[int, list[Moments]]:
        """Quantized Gram matrices per b and realization (computes only what is not cached)."""
        bits = parse_bits(bits)
        keys = {b: self.keys.moments(b) for b in bits}

        def compute(todo: list[int], deliver: Callable[[int, object], None]) -> None:
            for b, v in compute_moments(self, tuple(todo), progress).items():
                deliver(b, v)

        return cast(dict[int, list[Moments]], self.cache.batch(keys, compute))

    def _estimator(self, estimator: str | None) -> str:
        est = estimator or self.config.estimator
        check_choice("estimator", est, ESTIMATORS)
        return est

    def identification(self, b: int, estimator: str | None = None) -> BitsIdentification:
        """Identified models at word length ``b`` for every realization."""
        est = self._estimator(estimator)
        return self.cache.memo(self.keys.identification(b, est), lambda: identify_at(self, b, est))

    # ----- theory --------------------------------------------------------------------------
    def theory(self, b: int) -> TheoryAtBits:
        """Theorem 1 prediction and the ultimate bound delta(eps) at word length ``b``."""
        return self.cache.memo(self.keys.theory(b), lambda: theory_at(self, b))

    def realized_bound(self, b: int, estimator: str | None = None) -> RealizedBounds:
        """A-posteriori ultimate bound per realization at ``b``: its own model error and its own ``P``.

        See :func:`qsid_core.control.realized_bound.realized_bounds`; the MPC settings are the
        config's (or the defaults when MPC is off).
        """
        est = estimator or self.config.estimator
        return self.cache.memo(self.keys.realized_bound(b, est), lambda: realized_bound_at(self, b, est))

    def overload_effect(self, b: int) -> NDArray[np.float64]:
        """Predicted change of ``[A^, B^]`` caused by the quantizer clipping the data at ``b``, shape (n, n+m)
        (zeros when nothing clips; :func:`qsid_core.studies.assumptions.overload_effect`). Needs no quantized data, so
        it can be computed while the data are being quantized."""
        from .assumptions import overload_effect

        return self.cache.memo(self.keys.overload_effect(b), lambda: overload_effect(self, b))

    def overload_effects(self, bits: str | int | Sequence[int]) -> dict[int, NDArray[np.float64]]:
        """:meth:`overload_effect` at every b of ``bits``; the data's matrices, where a quantizer clips, are
        built once for all of them (a copy of the data, not kept)."""
        from .assumptions import overload_effect

        held: list[tuple[NDArray[np.float64], NDArray[np.float64]]] = []

        def matrices() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
            if not held:
                held.append(self.data.matrices())
            return held[0]

        def effect(b: int) -> NDArray[np.float64]:
            return self.cache.memo(self.keys.overload_effect(b), lambda: overload_effect(self, b, matrices))

        return {b: effect(b) for b in parse_bits(bits)}

    def assumptions(self, b: int) -> Assumptions:
        """Which hypotheses of Theorem 1 and of BCLS hold at ``b`` (see :mod:`qsid_core.studies.assumptions`)."""
        from .assumptions import assess

        return self.cache.memo(self.keys.assumptions(b), lambda: assess(self, b))

    # ----- MPC -----------------------------------------------------------------------------
    def feedback_range(self) -> FeedbackRange | None:
        """``(lo, hi, guard)`` of the training data's states, for a quantized measurement in the loop (else None)."""
        return feedback_range(self)

    def closed_loops(self, b: int, estimator: str | None = None) -> ClosedLoops:
        """Closed loops on the true system of the MPC built on each realization's model at ``b``."""
        cfg = mpc_of(self)
        est = estimator or self.config.estimator
        return self.cache.memo(self.keys.loops(b, est, cfg), lambda: run_closed_loops(*loop_args(self, b, est, cfg)))

    def closed_loops_many(
        self, bits: str | int | Sequence[int], estimator: str | None = None, progress: Progress | None = None
    ) -> dict[int, ClosedLoops]:
        """:meth:`closed_loops` for several b, mapped through the executor."""
        cfg = mpc_of(self)
        est = estimator or self.config.estimator
        bits = parse_bits(bits)
        keys = {b: self.keys.loops(b, est, cfg) for b in bits}

        def compute(todo: list[int], deliver: Callable[[int, object], None]) -> None:
            futs = {b: self.executor.submit(loops_task, loop_args(self, b, est, cfg)) for b in todo}
            for i, (b, f) in enumerate(futs.items()):
                deliver(b, f.result())
                if progress:
                    progress(i + 1, len(futs), "MPC closed loops")

        return cast(dict[int, ClosedLoops], self.cache.batch(keys, compute))

    def true_model_loop(self) -> ClosedLoops:
        """The MPC built on the true (A, B): the reference every quantized model is compared to."""
        cfg = mpc_of(self)
        return self.cache.memo(self.keys.true_loop(cfg), lambda: run_closed_loops(*true_loop_args(self, cfg)))
