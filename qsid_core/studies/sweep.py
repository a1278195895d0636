"""Whole sweeps over the word length.

:func:`run_sweep` runs every stage of an :class:`~qsid_core.studies.experiment.Experiment`
for all requested b (identification, Theorem 1 and the ultimate bound, MPC closed
loops) and returns a :class:`~qsid_core.studies.sweep_result.SweepResult`; :func:`summarize` is the
complete per-b summary of an experiment.
"""

from __future__ import annotations

import time
from concurrent.futures import Executor

import numpy as np

from ..control.loop_results import ClosedLoops
from .config import SweepConfig
from .config_checks import check_run_args
from .executors import single_threaded_blas
from .experiment import Experiment, Progress
from .summary import UNKNOWN, SummaryRow, fit_slope, summary_row
from .sweep_result import SweepResult

__all__ = ["run_sweep", "summarize"]


def summarize(ex: Experiment, b: int, estimator: str | None = None) -> SummaryRow:
    """The complete row of word length ``b`` from an experiment (closed loops when MPC is on, the
    a-posteriori bound, the assumptions and the saturated-steps count); every part is cached by ``ex``."""
    est = estimator or ex.config.estimator
    cfg = ex.config.mpc
    lp = ex.closed_loops(b, est) if cfg is not None else None
    u_max = cfg.resolve(ex.system).u_max if cfg is not None else UNKNOWN
    return summary_row(
        ex.system.n,
        ex.identification(b, est),
        ex.theory(b),
        lp,
        u_max=u_max,
        realized=ex.realized_bound(b, est),
        assumptions=ex.assumptions(b),
    )


def run_sweep(
    config: SweepConfig,
    executor: Executor | None = None,
    progress: Progress | None = None,
    experiment: Experiment | None = None,
    tasks: int = 4,
) -> SweepResult:
    """Run a whole sweep over ``config.bits``.

    Parameters
    ----------
    config : SweepConfig
    executor : Executor, optional
        Where independent tasks run (default in-process).
    progress : callable(done, total, stage), optional
        Called as work completes (the engine never prints).
    experiment : Experiment, optional
        Reuse its caches (e.g. a dashboard session).
    tasks : int
        Chunks the realizations are split into (use >= the executor's workers).

    Raises
    ------
    QsidError
        Only for bad settings (ConfigError, SystemDefinitionError) or data that
        overflow (DataOverflowError). Per-realization failures are *recorded*, not
        raised: identification (``BitsIdentification.failed`` and ``notes``), the
        ultimate bound (``delta = inf`` with ``bound_note``) and the closed loops
        (``ClosedLoops.failure`` / ``messages``); reported numbers are otherwise finite.
    """
    check_run_args(config, SweepConfig, executor, progress)
    with single_threaded_blas():
        t0 = time.perf_counter()
        ex = experiment.with_config(config) if experiment is not None else Experiment(config, executor, tasks)
        if executor is not None:
            ex.executor = executor
        _ = ex.prepared
        t1 = time.perf_counter()
        ex.moments(config.bits, progress)
        idents = {b: ex.identification(b) for b in config.bits}
        t2 = time.perf_counter()
        theory = {b: ex.theory(b) for b in config.bits}
        realized = {b: ex.realized_bound(b) for b in config.bits}
        assumptions = {b: ex.assumptions(b) for b in config.bits}
        t3 = time.perf_counter()
        loops: dict[int, ClosedLoops] = {}
        true_loop = None
        if config.mpc is not None:
            loops = ex.closed_loops_many(config.bits, progress=progress)
            true_loop = ex.true_model_loop()
        t4 = time.perf_counter()
    sA = fit_slope(config.bits, [np.mean(idents[b].err_A) for b in config.bits])
    sB = fit_slope(config.bits, [np.mean(idents[b].err_B) for b in config.bits])
    timing = {
        "data": round(t1 - t0, 4),
        "identify": round(t2 - t1, 4),
        "theory": round(t3 - t2, 4),
        "mpc": round(t4 - t3, 4),
        "total": round(time.perf_counter() - t0, 4),
    }
    prep = ex.prepared
    ranges = {"lo": prep.lo.tolist(), "hi": prep.hi.tolist()}
    return SweepResult(
        config,
        ex.system,
        config.bits,
        idents,
        theory,
        loops,
        true_loop,
        sA,
        sB,
        timing,
        realized,
        assumptions,
        ranges=ranges,
    )
