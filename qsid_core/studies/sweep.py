"""Whole sweeps over the word length.

:func:`run_sweep` runs every stage of an :class:`~qsid_core.studies.experiment.Experiment`
for all requested b (identification, Theorem 1 and the ultimate bound, MPC closed
loops) and returns a :class:`~qsid_core.studies.sweep_result.SweepResult`; :func:`summarize` is the
complete per-b summary of an experiment.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from ..control.loop_results import ClosedLoops
from ..control.realized_bound import RealizedBounds
from .config import SweepConfig
from .config_checks import check_run_args
from .executors import InlineExecutor, single_threaded_blas
from .experiment import Experiment, Progress
from .stage_results import BitsIdentification, TheoryAtBits
from .summary import UNKNOWN, SummaryRow, fit_slope, summary_row
from .sweep_result import SweepResult

if TYPE_CHECKING:
    from .assumptions import Assumptions

__all__ = ["run_sweep", "summarize"]

T = TypeVar("T")


def _start(side: ThreadPoolExecutor | None, fn: Callable[..., T], *args: Any) -> Future[T]:
    """``fn(*args)`` in the helper thread ``side``, or (None) here, at once, as a finished future."""
    if side is not None:
        return side.submit(fn, *args)
    done: Future[T] = Future()
    done.set_result(fn(*args))
    return done


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
        marks: list[float] = []
        idents, theory, realized, assumptions, loops, true_loop = _stages(ex, progress, marks)
        t2, t3, t4 = marks
    sA = fit_slope(config.bits, [np.mean(idents[b].err_A) for b in config.bits])
    sB = fit_slope(config.bits, [np.mean(idents[b].err_B) for b in config.bits])
    timing = {
        "data": round(t1 - t0, 4),
        "identify": round(t2 - t1, 4),  # with an executor: also Theorem 1 and the overload effects meanwhile
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


#: the stage results of a sweep: identification, theory, a-posteriori bounds, assumptions, closed loops,
#: the true model's loop (None without MPC), each by b
Stages = tuple[
    dict[int, BitsIdentification],
    dict[int, TheoryAtBits],
    dict[int, RealizedBounds],
    dict[int, "Assumptions"],
    dict[int, ClosedLoops],
    ClosedLoops | None,
]


def _stages(ex: Experiment, progress: Progress | None, marks: list[float]) -> Stages:
    """Every stage at every b of ``ex.config``; appends to ``marks`` when identification, the bounds and
    the closed loops are done.

    With an executor of its own (threads, processes, a cluster) the experiment quantizes and runs the closed
    loops there, submitted from a helper thread, while this thread computes what needs no quantized data
    (Theorem 1, the overload effects, the true model's loop) or no closed loops (the bounds and assumptions):
    the compiled kernels release the GIL. In-process, one after another.
    """
    bits, mpc = ex.config.bits, ex.config.mpc is not None
    side = None if isinstance(ex.executor, InlineExecutor) else ThreadPoolExecutor(1, "qsid-sweep")
    try:
        moments = _start(side, ex.moments, bits, progress)
        theory = {b: ex.theory(b) for b in bits}  # from the unquantized data
        ex.overload_effects(bits)
        if mpc and side is not None:
            ex.true_model_loop()
        moments.result()
        idents = {b: ex.identification(b) for b in bits}
        marks.append(time.perf_counter())
        closed = _start(side, ex.closed_loops_many, bits, None, progress) if mpc else None
        realized = {b: ex.realized_bound(b) for b in bits}
        assumptions = {b: ex.assumptions(b) for b in bits}
        marks.append(time.perf_counter())
        loops: dict[int, ClosedLoops] = closed.result() if closed is not None else {}
        true_loop = ex.true_model_loop() if mpc else None
        marks.append(time.perf_counter())
        return idents, theory, realized, assumptions, loops, true_loop
    finally:
        if side is not None:
            side.shutdown(wait=False, cancel_futures=True)
