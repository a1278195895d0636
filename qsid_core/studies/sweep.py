"""Whole sweeps over the word length, and their JSON-ready summaries.

:func:`run_sweep` runs every stage of an :class:`~qsid_core.studies.experiment.Experiment`
for all requested b (identification, Theorem 1 and the ultimate bound, MPC closed
loops) and returns a :class:`SweepResult`; :func:`summary_row` is the per-b summary
that the CLI prints as JSON and the figure builders draw.
"""

from __future__ import annotations

import time
from concurrent.futures import Executor
from dataclasses import dataclass, field

import numpy as np

from ..control.bound import RealizedBounds
from ..control.loop_results import ClosedLoops
from ..control.stability import data_rate_bits
from ..errors import ConfigError
from ..plant.lti import LTISystem
from ..quantization.quantize import ERROR_VARIANCE, NOMINAL_VARIANCE, bcls_reason
from ..version import __version__
from .assumptions import Assumptions
from .config import SweepConfig
from .config_checks import check_run_args
from .executors import single_threaded_blas
from .experiment import Experiment, Progress
from .stage_results import BitsIdentification, TheoryAtBits
from .summary import _UNKNOWN, SummaryRow, build_row, json_clean

__all__ = [
    "SweepResult",
    "StoredRow",
    "run_sweep",
    "summary_row",
    "summarize",
    "fit_slope",
    "load_result",
    "RESULT_FORMAT",
]

#: Version of the sweep result's JSON layout (the ``result_format`` key). 1: files without the key, whose
#: rows count the closed-loop steps that needed the QP solver as ``osqp_steps``; 2: that key is ``qp_steps``.
RESULT_FORMAT = 2


def fit_slope(bits, values) -> float:
    """Least-squares slope of ``log10(values)`` against ``bits`` (NaN if fewer than 2 usable points)."""
    b = np.asarray(bits, dtype=float)
    v = np.asarray(values, dtype=float)
    ok = np.isfinite(v) & (v > 0)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(b[ok], np.log10(v[ok]), 1)[0])


def summary_row(
    n: int,
    ident: BitsIdentification,
    th: TheoryAtBits,
    lp: ClosedLoops | None,
    *,
    u_max=_UNKNOWN,
    realized: RealizedBounds | None = None,
    assumptions: Assumptions | None = None,
) -> SummaryRow:
    """Typed summary of one word length (:class:`~qsid_core.studies.summary.SummaryRow`; ``.to_dict()`` is its JSON).

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
    return summary_row(
        ex.system.n,
        ex.identification(b, est),
        ex.theory(b),
        lp,
        u_max=u_max,
        realized=ex.realized_bound(b, est),
        assumptions=ex.assumptions(b),
    )


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
    rows : dict b -> StoredRow
        The per-b summaries of a result read back by :func:`load_result` (empty for a fresh sweep).
    version : str
        The qsid version that made a loaded result ("" for a fresh one: this version).
    ranges : dict or None
        The quantizer's data ranges ``{"lo": [...], "hi": [...]}`` (n + m channels).
    true_cost : float or None
        A loaded result's true-model MPC cost.
    true_errors : dict
        A loaded result's true-model ``steady_state_error`` and ``tracking_error``.
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

    rows: dict = field(default_factory=dict)
    version: str = ""
    ranges: dict | None = None
    true_cost: float | None = None
    true_errors: dict = field(default_factory=dict)

    def _check_bits(self, b) -> int:
        if isinstance(b, bool) or not isinstance(b, (int, np.integer)) or int(b) not in self.bits:
            swept = ", ".join(map(str, self.bits))
            raise ConfigError(f"b = {b!r} was not swept; this result has b = {swept}")
        return int(b)

    def summary(self, b: int) -> SummaryRow:
        """The typed summary at word length ``b``; ``.to_dict()`` is the CLI's ``results`` entry.

        A result read back by :func:`load_result` returns its stored row (a :class:`StoredRow`).

        Raises
        ------
        ConfigError
            If ``b`` was not swept (the message lists the swept b).
        """
        b = self._check_bits(b)
        if b not in self.identification:
            return self.rows[b]
        lp = self.loops.get(b)
        u_max = self.config.mpc.resolve(self.system).u_max if (lp is not None and self.config.mpc) else _UNKNOWN
        return summary_row(
            self.system.n,
            self.identification[b],
            self.theory[b],
            lp,
            u_max=u_max,
            realized=self.realized.get(b),
            assumptions=self.assumptions.get(b),
        )

    def to_dict(self) -> dict:
        """The whole sweep as strict JSON data (NaN and inf become None).

        ``config`` holds every setting (:meth:`SweepConfig.to_dict`: the full system, the MPC
        settings, seeds) so that ``SweepConfig.from_dict`` / ``qsid sweep --config`` re-run it;
        ``qsid_version`` says which qsid made it and ``ranges`` the quantizer's data ranges.
        """
        c = self.config
        q = c.quantizer
        cfg = c.to_dict(self.system)
        cfg["mpc"] = (
            None
            if c.mpc is None
            else {
                "horizon": c.mpc.horizon,
                "steps": c.mpc.steps,
                "u_max": list(c.mpc.u_max),
                "disturbance": c.mpc.disturbance,
                "disturbance_kind": c.mpc.disturbance_kind,
                "feedback_bits": c.mpc.feedback_bits,
                "feedback_noise": c.mpc.feedback_noise,
                "loop_seed": c.mpc.loop_seed,
                "tracking": c.mpc.tracking,
                "reference": c.mpc.reference
                if isinstance(c.mpc.reference, (str, type(None)))
                else [list(r) for r in c.mpc.reference],
            }
        )
        why = bcls_reason(q.dither)
        return json_clean(
            {
                "result_format": RESULT_FORMAT,
                "qsid_version": self.version or __version__,
                "system": self.system.name,
                "config": cfg,
                "ranges": self.ranges,
                "bcls": {
                    "applicable": not why,
                    "reason": why,
                    "D": f"eps^2/{round(1 / ERROR_VARIANCE.get(q.dither, NOMINAL_VARIANCE))}"
                    + (" (nominal)" if why else "")
                    + (" + sigma^2 (sensor noise)" if c.noise_known and any(v > 0 for v in c.noise) else ""),
                },
                "results": [self.summary(b).to_dict() for b in self.bits],
                "mpc_cost_true_model": self.true_cost if self.true_loop is None else float(self.true_loop.cost[0]),
                "steady_state_error_true_model": self.true_errors.get("steady_state_error")
                if self.true_loop is None
                else float(self.true_loop.steady_state_error[0]),
                "tracking_error_true_model": self.true_errors.get("tracking_error")
                if self.true_loop is None
                else float(self.true_loop.tracking_error[0]),
                "data_rate_bits": data_rate_bits(self.system.A),
                "slope_A": float(self.slope_A),
                "slope_B": float(self.slope_B),
                "timing_s": self.timing_s,
            }
        )

    # ----- notebooks ---------------------------------------------------------------------------
    def _table(self) -> tuple[list, list]:
        head = [
            "b",
            "estimator",
            "err_A mean",
            "err_A std",
            "err_B mean",
            "err_B std",
            "Thm1 A",
            "Thm1 B",
            "overload",
            "delta",
        ]
        out = []
        for b in self.bits:
            r = self.summary(b).to_dict()
            out.append(
                [
                    b,
                    self.config.estimator,
                    r["err_A"]["mean"],
                    r["err_A"]["std"],
                    r["err_B"]["mean"],
                    r["err_B"]["std"],
                    r["err_A_theory"],
                    r["err_B_theory"],
                    r["overload_fraction"],
                    r["ultimate_bound"],
                ]
            )
        return head, out

    def _title(self) -> str:
        c, q = self.config, self.config.quantizer
        ib = "" if c.input_bits is None else f", input bits {c.input_bits}"
        ib += "" if c.state_bits is None else f", state bits {','.join(map(str, c.state_bits))}"
        return (
            f"SweepResult: {self.system.name} ({self.system.n} states, {self.system.m} inputs), "
            f"b = {_bits_text(self.bits)}{ib}, {c.realizations} realizations, {c.trajectories} x {c.steps}, "
            f"dither {q.dither}, estimator {c.estimator}"
            + (", MPC off" if c.mpc is None else "")
            + (" (loaded: summaries only)" if self.rows and not self.identification else "")
        )

    def __repr__(self) -> str:
        """A few lines: the settings and one row per b (at most 12 rows; never the arrays)."""
        head, rows = self._table()
        fmt = lambda v: "-" if v is None else (f"{v:.3g}" if isinstance(v, float) else str(v))  # noqa: E731
        shown = rows if len(rows) <= 12 else rows[:6] + [["..."] * len(head)] + rows[-5:]
        lines = [self._title(), "  " + "  ".join(head)]
        lines += ["  " + "  ".join(fmt(v) for v in r) for r in shown]
        lines.append(
            f"  slope per bit: A {self.slope_A:+.3f}, B {self.slope_B:+.3f}; .to_frame(), .summary(b), .to_dict()"
        )
        return "\n".join(lines)[:2000]

    def _repr_html_(self) -> str:
        """An HTML table for notebooks (one row per b)."""
        import html

        head, rows = self._table()
        fmt = lambda v: "-" if v is None else (f"{v:.4g}" if isinstance(v, float) else str(v))  # noqa: E731
        th = "".join(f"<th>{html.escape(h)}</th>" for h in head)
        body = "".join("<tr>" + "".join(f"<td>{html.escape(fmt(v))}</td>" for v in r) + "</tr>" for r in rows)
        return (
            f"<div><p>{html.escape(self._title())}</p><table><thead><tr>{th}</tr></thead>"
            f"<tbody>{body}</tbody></table></div>"
        )

    def to_frame(self, pandas: bool = True):
        """One row per b and estimator: errors (mean, std), Theorem 1, overload, bound, MPC cost.

        Parameters
        ----------
        pandas : bool
            True: a ``pandas.DataFrame`` (raises ImportError with advice when pandas is missing);
            False: a dict of equal-length column lists.
        """
        head, rows = self._table()
        cols = {h.replace(" ", "_"): [r[i] for r in rows] for i, h in enumerate(head)}
        cols["mpc_cost_mean"] = [(self.summary(b).to_dict().get("mpc_cost") or {}).get("mean") for b in self.bits]
        if not pandas:
            return cols
        try:
            import pandas as pd
        except ImportError as exc:
            raise ImportError(
                "to_frame() needs pandas (pip install pandas); to_frame(pandas=False) gives plain column lists"
            ) from exc
        return pd.DataFrame(cols)


class StoredRow(dict):
    """A per-b summary read back from JSON (:func:`load_result`): a mapping with ``to_dict()``."""

    def to_dict(self) -> dict:
        return dict(self)


def _bits_text(bits) -> str:
    b = list(bits)
    if len(b) > 2 and b == list(range(b[0], b[-1] + 1)):
        return f"{b[0]}..{b[-1]}"
    return ",".join(map(str, b))


def _upgrade_row(row: dict, fmt: int) -> dict:
    """A per-b summary of JSON format ``fmt`` in the current format's keys (same order)."""
    if fmt < 2:
        row = {("qp_steps" if k == "osqp_steps" else k): v for k, v in row.items()}
    return row


def load_result(path) -> SweepResult:
    """Read a saved sweep (``qsid sweep --out FILE`` or ``json.dump(res.to_dict())``) back into a SweepResult.

    The result has the full config and system (so ``run_sweep(res.config)`` re-runs it to the
    same numbers), the per-b summaries (:meth:`SweepResult.summary`, ``to_frame``, ``to_dict``),
    slopes and timing; per-realization arrays are not in the JSON (``identification`` etc. are
    empty).

    Raises
    ------
    ConfigError
        If the file is missing, not JSON, or not a sweep result with a full config (files
        written before the config carried the system are refused with that reason), or its
        ``result_format`` is newer than :data:`RESULT_FORMAT`. Older formats are read and their
        rows renamed to the current keys (format 1's ``osqp_steps`` becomes ``qp_steps``).
    """
    import json
    from pathlib import Path

    from ..plant.systems import get_system

    p = Path(path)
    try:
        d = json.loads(p.read_text())
    except OSError as exc:
        raise ConfigError(f"cannot read {p}: {exc.strerror or exc}") from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{p} is not JSON ({exc})") from None
    if not isinstance(d, dict) or not isinstance(d.get("config"), dict) or not isinstance(d.get("results"), list):
        raise ConfigError(f"{p} is not a qsid sweep result (needs 'config' and 'results')")
    if "system_definition" not in d["config"]:
        raise ConfigError(
            f"{p} was written without the full configuration (no system_definition): "
            "re-run that sweep with this qsid to get a file that can be loaded"
        )
    fmt = d.get("result_format", 1)
    if not isinstance(fmt, int) or isinstance(fmt, bool) or fmt > RESULT_FORMAT:
        raise ConfigError(
            f"{p} has result_format {fmt!r}; this qsid reads formats 1 to {RESULT_FORMAT} (a newer qsid wrote it?)"
        )
    cfg = SweepConfig.from_dict(d["config"])
    rows = {int(r["bits"]): StoredRow(_upgrade_row(r, fmt)) for r in d["results"]}
    nan = float("nan")
    return SweepResult(
        cfg,
        get_system(cfg.system),
        tuple(sorted(rows)),
        {},
        {},
        {},
        None,
        d.get("slope_A") if d.get("slope_A") is not None else nan,
        d.get("slope_B") if d.get("slope_B") is not None else nan,
        d.get("timing_s") or {},
        rows=rows,
        version=str(d.get("qsid_version", "")),
        ranges=d.get("ranges"),
        true_cost=d.get("mpc_cost_true_model"),
        true_errors={k: d.get(f"{k}_true_model") for k in ("steady_state_error", "tracking_error")},
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
        loops: dict = {}
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
