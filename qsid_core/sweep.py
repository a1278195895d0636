"""Whole sweeps over the word length, and their JSON-ready summaries.

:func:`run_sweep` runs every stage of an :class:`~qsid_core.experiment.Experiment`
for all requested b (identification, Theorem 1 and the ultimate bound, MPC closed
loops) and returns a :class:`SweepResult`; :func:`summary_row` is the per-b summary
that the CLI prints as JSON and the figure builders draw.
"""

from __future__ import annotations

import time
from concurrent.futures import Executor
from dataclasses import dataclass, field

import numpy as np

from .assumptions import Assumptions
from .closed_loop import ClosedLoops
from .experiment import BitsIdentification, Experiment, Progress, SweepConfig, TheoryAtBits, single_threaded_blas
from .summary import _UNKNOWN, SummaryRow, build_row, json_clean
from .systems import LTISystem
from .quantize import ERROR_VARIANCE, NOMINAL_VARIANCE, bcls_reason
from .theory import RealizedBounds
from .config_checks import check_run_args

__all__ = ["SweepResult", "SummaryRow", "run_sweep", "summary_row", "summarize", "fit_slope"]


def fit_slope(bits, values) -> float:
    """Least-squares slope of ``log10(values)`` against ``bits`` (NaN if fewer than 2 usable points)."""
    b = np.asarray(bits, dtype=float)
    v = np.asarray(values, dtype=float)
    ok = np.isfinite(v) & (v > 0)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(b[ok], np.log10(v[ok]), 1)[0])


def summary_row(n: int, ident: "BitsIdentification", th: "TheoryAtBits", lp: ClosedLoops | None, *,
                u_max=_UNKNOWN, realized: RealizedBounds | None = None,
                assumptions: Assumptions | None = None) -> SummaryRow:
    """Typed summary of one word length (:class:`~qsid_core.summary.SummaryRow`; ``.to_dict()`` is its JSON).

    Parameters
    ----------
    n : int
        Number of states (splits eps into states and inputs).
    ident, th, lp
        Results of :meth:`Experiment.identification`, :meth:`Experiment.theory` and
        :meth:`Experiment.closed_loops` (``lp`` may be None when MPC is off).
    u_max : array_like or None, optional
        Input bounds, for the count of saturated closed-loop steps.
    realized : RealizedBounds, optional
        The a-posteriori bound (:meth:`Experiment.realized_bound`).
    assumptions : Assumptions, optional
        (:meth:`Experiment.assumptions`).
    """
    return build_row(n, ident, th, lp, u_max=u_max, realized=realized, assumptions=assumptions)


def summarize(ex: Experiment, b: int, estimator: str | None = None) -> SummaryRow:
    """The complete row of word length ``b`` from an experiment (closed loops when MPC is on, the
    a-posteriori bound, the assumptions and the saturated-steps count); every part is cached by ``ex``."""
    est = estimator or ex.config.estimator
    cfg = ex.config.mpc
    lp = ex.closed_loops(b, est) if cfg is not None else None
    u_max = cfg.resolve(ex.system).u_max if cfg is not None else _UNKNOWN
    return summary_row(ex.system.n, ex.identification(b, est), ex.theory(b), lp, u_max=u_max,
                       realized=ex.realized_bound(b, est), assumptions=ex.assumptions(b))


@dataclass
class SweepResult:
    """A finished sweep: per-b summaries plus per-realization arrays.

    Attributes
    ----------
    config : SweepConfig
    bits : tuple of int
    identification : dict b -> BitsIdentification
    theory : dict b -> TheoryAtBits
    loops : dict b -> ClosedLoops (empty when MPC is off)
    true_loop : ClosedLoops or None
    slope_A, slope_B : float
        LS slope of log10(mean relative error) against b.
    timing_s : dict
        Wall-clock seconds per stage.
    realized : dict b -> RealizedBounds
        A-posteriori ultimate bounds (each realization's own model error and P).
    assumptions : dict b -> Assumptions
        Hypotheses of Theorem 1 and BCLS per b.
    """

    config: SweepConfig
    system: LTISystem
    bits: tuple
    identification: dict
    theory: dict
    loops: dict
    true_loop: ClosedLoops | None
    slope_A: float
    slope_B: float
    timing_s: dict
    realized: dict = field(default_factory=dict)
    assumptions: dict = field(default_factory=dict)

    def summary(self, b: int) -> SummaryRow:
        """The typed summary at word length ``b``; ``.to_dict()`` is the CLI's ``results`` entry."""
        lp = self.loops.get(b)
        u_max = self.config.mpc.resolve(self.system).u_max if (lp is not None and self.config.mpc) else _UNKNOWN
        return summary_row(self.system.n, self.identification[b], self.theory[b], lp, u_max=u_max,
                           realized=self.realized.get(b), assumptions=self.assumptions.get(b))

    def to_dict(self) -> dict:
        """The whole sweep as strict JSON data (NaN and inf become None)."""
        c = self.config
        q = c.quantizer
        return json_clean({
            "system": self.system.name,
            "config": {
                "bits": list(self.bits), "realizations": c.realizations, "trajectories": c.trajectories,
                "steps": c.steps, "data_seed": c.data_seed, "dither_seed": c.dither_seed, "dither": q.dither,
                "range": q.range_mode, "guard": q.guard, "estimator": c.estimator,
                "mpc": None if c.mpc is None else {
                    "horizon": c.mpc.horizon, "steps": c.mpc.steps, "u_max": list(c.mpc.u_max),
                },
                "theta": c.theta, "rho": c.rho, "input_amplitude": c.input_amplitude,
                "fixed_range": None if q.fixed_range is None else [list(p) for p in q.fixed_range],
            },
            "bcls": {"applicable": not bcls_reason(q.dither), "reason": bcls_reason(q.dither),
                     "D": "eps^2/%d" % round(1 / ERROR_VARIANCE.get(q.dither, NOMINAL_VARIANCE))
                     + (" (nominal)" if bcls_reason(q.dither) else "")},
            "results": [self.summary(b).to_dict() for b in self.bits],
            "mpc_cost_true_model": None if self.true_loop is None else float(self.true_loop.cost[0]),
            "slope_A": float(self.slope_A),
            "slope_B": float(self.slope_B),
            "timing_s": self.timing_s,
        })


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
        loops: dict = {}
        true_loop = None
        if config.mpc is not None:
            loops = ex.closed_loops_many(config.bits, progress=progress)
            true_loop = ex.true_model_loop()
        t4 = time.perf_counter()
    sA = fit_slope(config.bits, [np.mean(idents[b].err_A) for b in config.bits])
    sB = fit_slope(config.bits, [np.mean(idents[b].err_B) for b in config.bits])
    timing = {
        "data": round(t1 - t0, 4), "identify": round(t2 - t1, 4), "theory": round(t3 - t2, 4),
        "mpc": round(t4 - t3, 4), "total": round(time.perf_counter() - t0, 4),
    }
    return SweepResult(config, ex.system, config.bits, idents, theory, loops, true_loop, sA, sB, timing,
                       realized, assumptions)
