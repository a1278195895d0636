"""Whole sweeps over the word length, of either plant kind: :func:`run_sweep` chooses by the config.

For a linear plant (:class:`~qsid_core.studies.SweepConfig`) it runs every stage of an
:class:`~qsid_core.studies.experiment.Experiment` for all requested b (identification, Theorem 1 and the ultimate
bound, MPC closed loops) and returns a :class:`~qsid_core.studies.sweep_result.SweepResult`; :func:`summarize` is
the complete per-b summary of an experiment.

For a nonlinear plant (:class:`~qsid_core.studies.KoopmanConfig`, :func:`run_koopman_sweep`), for each
realization (an independent dither draw shared by every word length, as for a linear plant) and each word length
``b``: the lifted moments of the quantized training data (:func:`~qsid_core.identification.quantized_lifted_moments`),
the lifted model by the chosen estimator (:func:`~qsid_core.identification.edmd`), its relative errors against the
EDMD of the *same unquantized data*, its multi-step prediction error on held-out runs of the true plant, and the
Koopman MPC built on it run on the true plant from the plant's ``x0``
(:func:`~qsid_core.control.run_koopman_loops`); a :class:`KoopmanResult`. The linear certificates (Theorem 1's
error model, the small-gain and ultimate-bound results) assume a linear plant: they are not computed there and the
result says so (:data:`~qsid_core.studies.NO_CERTIFICATES`). The rows are the stages of a
:class:`~qsid_core.studies.KoopmanExperiment` (the nonlinear half of :class:`~qsid_core.Study`), so the whole sweep
and a study shown b by b are one computation.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar, overload

import numpy as np

from ..control.loop_results import ClosedLoops
from ..control.realized_bound import RealizedBounds
from ..errors import ConfigError
from ..identification import LARGE_DATA_HYPOTHESES
from ..plant import NonlinearSystem
from .config import HELD_OUT, NO_CERTIFICATES, KoopmanConfig, SweepConfig
from .config_checks import check_run_args
from .executors import InlineExecutor, single_threaded_blas
from .experiment import Experiment, Progress
from .stage_results import BitsIdentification, TheoryAtBits
from .study_nonlinear import KoopmanExperiment
from .summary import UNKNOWN, SummaryRow, fit_slope, summary_row
from .sweep_result import SweepResult

if TYPE_CHECKING:
    from .assumptions import Assumptions

__all__ = ["KoopmanResult", "run_koopman_sweep", "run_sweep", "summarize"]

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


@overload
def run_sweep(
    config: SweepConfig,
    executor: Executor | None = None,
    progress: Progress | None = None,
    experiment: Experiment | None = None,
    tasks: int = 4,
) -> SweepResult: ...
@overload
def run_sweep(
    config: KoopmanConfig,
    executor: Executor | None = None,
    progress: Progress | None = None,
    experiment: KoopmanExperiment | None = None,
    tasks: int = 4,
) -> KoopmanResult: ...
def run_sweep(
    config: SweepConfig | KoopmanConfig,
    executor: Executor | None = None,
    progress: Progress | None = None,
    experiment: Experiment | KoopmanExperiment | None = None,
    tasks: int = 4,
) -> SweepResult | KoopmanResult:
    """Run a whole sweep over ``config.bits``.

    Parameters
    ----------
    config : SweepConfig or KoopmanConfig
        A nonlinear plant's config runs :func:`run_koopman_sweep` (with ``experiment``, if given; the other
        arguments are a linear plant's).
    executor : Executor, optional
        Where independent tasks run (default in-process).
    progress : callable(done, total, stage), optional
        Called as work completes (the engine never prints).
    experiment : Experiment or KoopmanExperiment, optional
        Reuse its caches (e.g. a dashboard session, or a :class:`~qsid_core.Study`'s).
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
    if isinstance(config, KoopmanConfig):
        if experiment is not None and not isinstance(experiment, KoopmanExperiment):
            raise ConfigError("experiment: a nonlinear plant's sweep reuses a KoopmanExperiment, not an Experiment")
        return run_koopman_sweep(config, experiment)
    if experiment is not None and not isinstance(experiment, Experiment):
        raise ConfigError("experiment: a linear plant's sweep reuses an Experiment, not a KoopmanExperiment")
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


@dataclass
class KoopmanResult:
    """A finished nonlinear sweep: one row per word length, and what they are compared with.

    Attributes
    ----------
    config : KoopmanConfig
    rows : list of dict
        Per b (JSON-ready): ``bits``, ``eps_x``, ``eps_u``, ``err_G`` / ``err_A`` / ``err_B`` and
        ``prediction_error`` as ``{mean, std}``, ``overload_fraction``, ``bcls_fallbacks``,
        ``ident_failures``, ``stabilized_fraction``, ``closed_loop_outcomes``, ``within_radius`` (loops ending within ``radius``) and
        ``settled_offset`` ({median, max}) (None without loops),
        ``large_data`` (the estimator's large-data limit: ``err_G`` against the unquantized EDMD, None with a
        ``note`` where no exact formula exists), ``notes``.
    reference_prediction_error : float
        The unquantized EDMD's prediction error (the floor the quantized models approach).
    reference_outcome : str or None
        The unquantized EDMD's Koopman MPC verdict.
    reference_offset : float or None
        Its loop's settled offset: what the dictionary alone leaves (NaN: the loop diverged or failed).
    data_report : str
        Runs left out of the training data ("" when none).
    timing_s : float
    """

    config: KoopmanConfig
    rows: list[dict[str, Any]]
    reference_prediction_error: float
    reference_outcome: str | None
    data_report: str
    features: int
    runs_used: int
    timing_s: float = 0.0
    reference_offset: float | None = None

    def _mpc(self, s: NonlinearSystem) -> dict[str, Any]:
        """The loops' settings as run (the plant's defaults where the config leaves them unset)."""
        m = self.config.mpc
        assert m is not None
        return {
            "horizon": m.horizon,
            "steps": m.steps,
            "u_max": list(m.u_max) if isinstance(m.u_max, tuple) else [m.u_max],
            "x0": list(m.x0 or s.x0),
            "Q": list(m.Q or s.Q),
            "R": list(m.R or s.R),
            "terminal_weight": "C'QC" if self.config.lifting != "identity" else "DARE",
        }

    def to_dict(self) -> dict[str, Any]:
        """Strict-JSON-ready summary."""
        c = self.config
        s = c.plant()
        q = c.quantizer
        return {
            "kind": "koopman",
            "system": s.name,
            "config": {
                "lifting": c.lifting,
                "features": self.features,
                "estimator": c.estimator,
                "bits": list(c.bits),
                "trajectories": c.trajectories,
                "steps": c.steps,
                "realizations": c.realizations,
                "data_seed": c.data_seed,
                "dither_seed": c.dither_seed,
                "state_amplitude": s.amplitude,
                "input_amplitude": c.input_amplitude,
                "box": s.box,
                "dither": q.dither,
                "range": q.range_mode,
                "guard": q.guard,
                "mpc": None if c.mpc is None else self._mpc(s),
                "convergence_radius": c.radius,
                "held_out": {"runs": HELD_OUT[0], "steps": HELD_OUT[1], "horizon": c.prediction_horizon},
            },
            "data": {"runs_used": self.runs_used, "left_box": self.data_report},
            "certificates": NO_CERTIFICATES,
            "large_data_hypotheses": list(LARGE_DATA_HYPOTHESES),
            "reference": {
                "prediction_error": self.reference_prediction_error,
                "closed_loop_outcome": self.reference_outcome,
                "settled_offset": self.reference_offset,
            },
            "results": self.rows,
            "timing_s": {"total": self.timing_s},
        }


def run_koopman_sweep(cfg: KoopmanConfig, experiment: KoopmanExperiment | None = None) -> KoopmanResult:
    """Run the sweep (see the module docstring): every row of ``cfg.bits`` by ``cfg.estimator``, from the stages of
    a :class:`~qsid_core.studies.KoopmanExperiment` (``experiment``'s, whose cache it then shares, if it is of
    ``cfg``; else a new one).

    Raises
    ------
    ConfigError, SystemDefinitionError, IdentificationError
        Bad settings, a vector field that fails, or no model from the unquantized data.
    """
    t0 = time.perf_counter()
    ex = experiment if experiment is not None and experiment.config == cfg else KoopmanExperiment(cfg)
    data, _ = ex.data()
    ref_loop = ex.reference_loop()
    ex.moments(cfg.bits)  # one pass over the data per realization for every b
    rows = [ex.row(b, cfg.estimator) for b in cfg.bits]
    return KoopmanResult(
        cfg,
        rows,
        ex.reference()[1],
        None if ref_loop is None else ref_loop.outcome[0],
        data.report,
        ex.lifting.L,
        data.trajectories,
        time.perf_counter() - t0,
        None if ref_loop is None else float(ref_loop.settled_offset[0]),
    )
