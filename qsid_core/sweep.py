"""Whole sweeps over the word length, and their JSON-ready summaries.

:func:`run_sweep` runs every stage of an :class:`~qsid_core.experiment.Experiment`
for all requested b (identification, Theorem 1 and the ultimate bound, MPC closed
loops) and returns a :class:`SweepResult`; :func:`summary_row` is the per-b summary
that the CLI prints as JSON and the figure builders draw.
"""

from __future__ import annotations

import time
from concurrent.futures import Executor
from dataclasses import dataclass

import numpy as np

from .closed_loop import ClosedLoops
from .experiment import BitsIdentification, Experiment, Progress, SweepConfig, TheoryAtBits, single_threaded_blas
from .systems import LTISystem
from .config_checks import check_run_args

__all__ = ["SweepResult", "run_sweep", "summary_row", "fit_slope"]


def fit_slope(bits, values) -> float:
    """Least-squares slope of ``log10(values)`` against ``bits`` (NaN if fewer than 2 usable points)."""
    b = np.asarray(bits, dtype=float)
    v = np.asarray(values, dtype=float)
    ok = np.isfinite(v) & (v > 0)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(b[ok], np.log10(v[ok]), 1)[0])


def _stats(x: np.ndarray) -> dict:
    x = np.asarray(x, dtype=float)
    ok = x[np.isfinite(x)]
    return {"mean": float(ok.mean()) if ok.size else None, "std": float(ok.std()) if ok.size else None}


def _num(x: float):
    return None if x is None or not np.isfinite(x) else float(x)


def summary_row(n: int, ident: "BitsIdentification", th: "TheoryAtBits", lp: ClosedLoops | None) -> dict:
    """JSON-ready summary of one word length: errors (mean/std), theory, overload, MPC cost, bound.

    Parameters
    ----------
    n : int
        Number of states (splits eps into states and inputs).
    ident, th, lp
        Results of :meth:`Experiment.identification`, :meth:`Experiment.theory` and
        :meth:`Experiment.closed_loops` (``lp`` may be None when MPC is off).
    """
    row = {
        "bits": ident.bits,
        "eps_x": [_num(e) for e in ident.eps[:n]],  # strict JSON: a non-finite eps is null
        "eps_u": [_num(e) for e in ident.eps[n:]],
        "err_A": _stats(ident.err_A),
        "err_B": _stats(ident.err_B),
        "err_A_theory": _num(th.err_A),
        "err_B_theory": _num(th.err_B),
        "overload_fraction": float(ident.overload.mean()),
        "bcls_fallbacks": int(ident.fallback.sum()),
        "ultimate_bound": _num(th.delta),
        "ultimate_bound_note": th.bound_note,
        "ident_failures": int(ident.failed.sum()),
    }
    if lp is not None:
        failed = lp.failed
        fsn = lp.final_state_norm[~failed]
        kinds: dict = {}
        for f in lp.failure:
            if f:
                kinds[f] = kinds.get(f, 0) + 1
        row["mpc_cost"] = {**_stats(lp.cost), "failed": int(failed.sum()), "failures": kinds}
        row["final_state_norm"] = {
            "mean": float(fsn.mean()) if fsn.size else None,
            "max": float(fsn.max()) if fsn.size else None,
        }
        row["osqp_steps"] = lp.osqp_steps
    else:
        row["mpc_cost"] = None
        row["final_state_norm"] = None
    return row


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

    def summary(self, b: int) -> dict:
        """The JSON-ready summary at word length ``b`` (the CLI's ``results`` entries)."""
        return summary_row(self.system.n, self.identification[b], self.theory[b], self.loops.get(b))

    def to_dict(self) -> dict:
        """The whole sweep as plain JSON-ready data."""
        c = self.config
        q = c.quantizer
        return {
            "system": self.system.name,
            "config": {
                "bits": list(self.bits), "realizations": c.realizations, "trajectories": c.trajectories,
                "steps": c.steps, "data_seed": c.data_seed, "dither_seed": c.dither_seed, "dither": q.dither,
                "range": q.range_mode, "guard": q.guard, "estimator": c.estimator,
                "mpc": None if c.mpc is None else {
                    "horizon": c.mpc.horizon, "steps": c.mpc.steps, "u_max": list(c.mpc.u_max),
                },
                "theta": c.theta, "rho": c.rho,
            },
            "results": [self.summary(b) for b in self.bits],
            "mpc_cost_true_model": None if self.true_loop is None else _num(self.true_loop.cost[0]),
            "slope_A": _num(self.slope_A),
            "slope_B": _num(self.slope_B),
            "timing_s": self.timing_s,
        }


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
    return SweepResult(config, ex.system, config.bits, idents, theory, loops, true_loop, sA, sB, timing)
