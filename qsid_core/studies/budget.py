"""A fixed budget of bits: fewer, finer samples or more, coarser ones?

A sensor link carries ``T`` bits. Every sample of every state and input channel is sent at ``b`` bits, so a run of
``S`` steps costs ``S (n + m) b`` bits and the budget buys ``floor(T / (S (n + m) b))`` runs at word length ``b``.
For each ``b`` of the study the data set it buys is identified by the sweep's own stages (linear plants:
:class:`~qsid_core.studies.experiment.Experiment`; nonlinear ones: quantized EDMD,
:class:`~qsid_core.studies.study_nonlinear.KoopmanExperiment`), ``realizations`` times, each realization with its
own data, sensor noise and dither (:mod:`~qsid_core.studies.budget_tasks`), and, with an MPC, the loops built on
the models are run on the true plant.

Per b: the runs bought, the model error ``err_G`` (relative Frobenius error of ``[A^, B^]``; of the lifted model
against the unquantized EDMD for a nonlinear plant) as mean and std over the realizations, Theorem 1's LS limit
and the predicted error (:mod:`~qsid_core.studies.budget_model`, linear plants, subtractive dither), and the
loops' stabilized share and cost gap to the true-model MPC. Then

``b_best``
    the b of least mean error;
``b_knee``
    the smallest b whose mean error is within ``knee`` (25 %) of the least (``b_knee_predicted``: the same on the
    predicted curve);
``b_loop``
    the smallest b whose loops meet the target of ``qsid bits`` (at least ``target`` stabilized, cost within
    ``cost_gap`` of the true model's; for a nonlinear plant the stabilized share alone, its loops judged
    converged only when they settle at the origin, :mod:`~qsid_core.control.koopman_mpc`).

A b whose budget buys no run, or fewer samples than unknowns per row, is a row marked not identifiable.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..control.closed_loop import run_closed_loops
from ..errors import ConfigError, check_float, check_int
from ..plant.systems import get_system
from .bits_answer import check_targets
from .budget_tasks import Plan, linear_realization, nonlinear_realization
from .config import KoopmanConfig, SweepConfig
from .executors import InlineExecutor
from .loop_stages import loops_task
from .summary import Stats, json_clean

__all__ = ["KNEE_TOLERANCE", "BudgetConfig", "BudgetResult", "runs_bought", "run_budget"]

#: ``b_knee``: the smallest b whose mean error is within this share of the least.
KNEE_TOLERANCE = 0.25
#: The largest budget accepted (bits).
MAX_TOTAL_BITS = 1e15


def runs_bought(total_bits: float, steps: int, channels: int, b: int) -> int:
    """``floor(T / (S (n + m) b))``: the runs of ``steps`` samples a budget of ``total_bits`` buys at ``b`` bits."""
    return int(math.floor(total_bits / (steps * channels * b) + 1e-9))


@dataclass(frozen=True)
class BudgetConfig:
    """A budget study.

    Parameters
    ----------
    total_bits : float, > 0
        The bits the link carries (``4e7``); a whole number.
    study : SweepConfig or KoopmanConfig
        Everything else, as for a sweep: system, word lengths ``bits``, ``steps`` per run, ``realizations``,
        quantizer, estimator, sensor noise, seeds, MPC (None: no loops), lifting for a nonlinear plant. Its
        ``trajectories`` is not used: the budget sets it per b. Every channel is sent at the swept b
        (``input_bits`` and ``state_bits`` must be unset).
    target, cost_gap : float
        The loops' target, as in :func:`~qsid_core.studies.bits_needed` (0.95 and 0.01).
    knee : float, > 0
        ``b_knee``'s tolerance (:data:`KNEE_TOLERANCE`).
    bits_per_sample : int, optional
        Bits per sample over all ``n + m`` channels: the study is then the per-channel allocation
        (:func:`~qsid_core.studies.run_allocation`: the proposed split against the uniform one, at the
        ``floor(T / (steps bits_per_sample))`` runs the budget buys). Linear plants, subtractive dither.
    """

    total_bits: float
    study: SweepConfig | KoopmanConfig = field(
        default_factory=lambda: SweepConfig(system="boeing747", steps=100, realizations=20)
    )
    target: float = 0.95
    cost_gap: float = 0.01
    knee: float = KNEE_TOLERANCE
    bits_per_sample: int | None = None

    def __post_init__(self) -> None:
        tb = check_float("total bits", self.total_bits, 1.0, MAX_TOTAL_BITS)
        if tb != math.floor(tb):
            raise ConfigError(f"total bits must be a whole number of bits; got {tb:g}")
        object.__setattr__(self, "total_bits", tb)
        if not isinstance(self.study, (SweepConfig, KoopmanConfig)):
            raise ConfigError(f"study must be a SweepConfig or a KoopmanConfig; got {type(self.study).__name__}")
        if isinstance(self.study, SweepConfig) and (
            self.study.input_bits is not None or self.study.state_bits is not None
        ):
            raise ConfigError("input bits / state bits: a budget sends every channel at the swept b; leave them unset")
        t, g = check_targets(self.target, self.cost_gap)
        object.__setattr__(self, "target", t)
        object.__setattr__(self, "cost_gap", g)
        object.__setattr__(self, "knee", check_float("knee", self.knee, 0.0, 10.0, lo_open=True))
        if self.bits_per_sample is not None:  # from one bit per channel to 32 each; linear plants, subtractive dither
            if self.nonlinear or self.study.quantizer.dither != "subtractive":
                raise ConfigError(
                    "bits per sample: the allocation's error model is for linear plants, subtractive dither"
                )
            p = sum(self.shape()[1:3])
            object.__setattr__(self, "bits_per_sample", check_int("bits per sample", self.bits_per_sample, p, 32 * p))

    @property
    def nonlinear(self) -> bool:
        return isinstance(self.study, KoopmanConfig)

    def shape(self) -> tuple[str, int, int, int]:
        """``(plant name, n, m, unknowns per row)``: the unknowns are ``n + m`` (``L + m`` lifted)."""
        s = self.study
        if isinstance(s, KoopmanConfig):
            p = s.plant()
            return p.name, p.n, p.m, s.dictionary().L + p.m
        sysm = get_system(s.system)
        return sysm.name, sysm.n, sysm.m, sysm.n + sysm.m

    def plan(self) -> tuple[Plan, dict[int, str]]:
        """The identifiable ``((b, runs), ...)`` and, for every other b, why not.

        Raises
        ------
        ConfigError
            No b is identifiable, or a b buys more runs than one data set may hold.
        """
        _, n, m, unknowns = self.shape()
        S = self.study.steps
        plan, skipped = [], {}
        for b in self.study.bits:
            runs = runs_bought(self.total_bits, S, n + m, b)
            if runs < 1:
                skipped[b] = f"the budget buys no run of {S} steps at b = {b} ({S * (n + m) * b} bits each)"
            elif runs * S < unknowns:
                skipped[b] = f"{runs} run(s) of {S} steps give {runs * S} samples, fewer than the {unknowns} unknowns"
            elif runs > 100_000:
                raise ConfigError(
                    f"total bits: {self.total_bits:g} bits buy {runs} runs of {S} steps at b = {b}, more than "
                    "100000; use a smaller budget or longer runs (steps)"
                )
            else:
                plan.append((b, runs))
        if not plan:
            need = S * (n + m) * self.study.bits[0] * math.ceil(unknowns / S)
            raise ConfigError(
                f"total bits: {self.total_bits:g} bits identify nothing at any b of {list(self.study.bits)} "
                f"(runs of {S} steps, {n + m} channels); at least {need} bits are needed at b = {self.study.bits[0]}"
            )
        return tuple(plan), skipped


@dataclass
class BudgetResult:
    """A finished budget study: one row per word length (:meth:`to_dict` is the JSON the CLI prints)."""

    config: BudgetConfig
    system: str
    rows: list[dict[str, Any]]
    true_cost: float | None
    timing_s: float = 0.0

    def _pick(self, key: str) -> int | None:
        vals = {r["bits"]: r[key] for r in self.rows if r[key] is not None and np.isfinite(r[key])}
        return min(vals, key=lambda b: (vals[b], b)) if vals else None

    def _knee(self, key: str) -> int | None:
        best = self._pick(key)
        if best is None:
            return None
        lim = (1.0 + self.config.knee) * next(r[key] for r in self.rows if r["bits"] == best)
        return int(min(r["bits"] for r in self.rows if r[key] is not None and np.isfinite(r[key]) and r[key] <= lim))

    @property
    def b_best(self) -> int | None:
        """The b of least mean error."""
        return self._pick("_err")

    @property
    def b_knee(self) -> int | None:
        """The smallest b whose mean error is within ``knee`` of the least."""
        return self._knee("_err")

    @property
    def b_knee_predicted(self) -> int | None:
        """``b_knee`` on the predicted curve (None without a prediction)."""
        return self._knee("_pred")

    @property
    def b_loop(self) -> int | None:
        """The smallest b whose loops meet the target (None: none does, or no loops)."""
        return next((r["bits"] for r in self.rows if r.get("meets_target")), None)

    def to_dict(self) -> dict[str, Any]:
        c, s = self.config, self.config.study
        q = s.quantizer
        settings: dict[str, Any] = {
            "total_bits": c.total_bits,
            "bits": list(s.bits),
            "steps": s.steps,
            "realizations": s.realizations,
            "estimator": s.estimator,
            "dither": q.dither,
            "range": q.range_mode,
            "guard": q.guard,
            "data_seed": s.data_seed,
            "dither_seed": s.dither_seed,
            "mpc": s.mpc is not None,
            "target": c.target,
            "cost_gap": c.cost_gap,
            "knee": c.knee,
        }
        if isinstance(s, KoopmanConfig):
            settings["lifting"] = s.lifting
        else:
            settings.update(noise=list(s.noise), noise_known=s.noise_known)
        out: dict[str, Any] = json_clean(
            {
                "kind": "budget",
                "system": self.system,
                "nonlinear": c.nonlinear,
                "config": settings,
                "rows": [{k: v for k, v in r.items() if not k.startswith("_")} for r in self.rows],
                "b_best": self.b_best,
                "b_knee": self.b_knee,
                "b_knee_predicted": self.b_knee_predicted,
                "b_loop": self.b_loop,
                "true_model_cost": self.true_cost,
                "timing_s": {"total": round(self.timing_s, 4)},
            }
        )
        return out


Progress = Callable[[int, int, str], None]


def run_budget(
    config: BudgetConfig, executor: Executor | None = None, progress: Progress | None = None
) -> BudgetResult:
    """Run the budget study of ``config`` (see the module docstring).

    Parameters
    ----------
    config : BudgetConfig
    executor : Executor, optional
        Runs the realizations (one task each) and the loops of each b (default: in-process).
    progress : callable(done, total, stage), optional

    Raises
    ------
    ConfigError
        Bad settings, or a budget that identifies nothing at any b.
    """
    if not isinstance(config, BudgetConfig):
        raise ConfigError(f"config must be a BudgetConfig; got {type(config).__name__}")
    if config.bits_per_sample is not None:
        raise ConfigError("bits per sample: a per-channel allocation study; run it with run_allocation")
    t0 = time.perf_counter()
    pool = executor or InlineExecutor()
    plan, skipped = config.plan()
    study = config.study
    if isinstance(study, SweepConfig):  # the plant resolved once, not once per realization and word length
        study = replace(study, system=get_system(study.system))
    name = config.shape()[0]
    # a nonlinear plant: a task per realization and word length (each b its own experiment: short tasks)
    task: Callable[..., list[dict[str, Any]]] = linear_realization
    chunks: list[Plan] = [plan]
    if isinstance(study, KoopmanConfig):
        task, chunks = nonlinear_realization, [(p,) for p in plan]
    futs = [[pool.submit(task, study, part, r) for part in chunks] for r in range(study.realizations)]
    per: list[list[dict[str, Any]]] = []
    for i, fs in enumerate(futs):
        per.append([row for f in fs for row in f.result()])
        if progress:
            progress(i + 1, len(futs), "realizations")
    parts = {b: [p[j] for p in per] for j, (b, _) in enumerate(plan)}
    runs = dict(plan)
    true_cost = None
    loops: dict[int, Any] = {}
    if isinstance(study, SweepConfig) and study.mpc is not None:
        loops, true_cost = _linear_loops(study, parts, pool, progress)
    rows = []
    for b in study.bits:
        if b in skipped:
            rows.append(_skipped_row(config, b, skipped[b]))
        else:
            rows.append(_row(config, b, runs[b], parts[b], loops.get(b), true_cost))
    return BudgetResult(config, name, rows, true_cost, time.perf_counter() - t0)


def _linear_loops(
    study: SweepConfig, parts: dict[int, list[dict[str, Any]]], pool: Executor, progress: Progress | None
) -> tuple[dict[int, Any], float | None]:
    """The closed loops of every realization's model at each b, and the true-model MPC's cost."""
    system = get_system(study.system)
    mpc = study.mpc
    assert mpc is not None
    A, B = system.A, system.B
    futs = {}
    for b, ps in parts.items():
        frange = (*ps[0]["range"], study.quantizer.guard) if mpc.feedback_bits is not None else None
        futs[b] = pool.submit(loops_task, ([(p["A"], p["B"]) for p in ps], A, B, mpc, system, frange))
    out = {}
    for i, (b, f) in enumerate(futs.items()):
        out[b] = f.result()
        if progress:
            progress(i + 1, len(futs), "MPC closed loops")
    ps0 = next(iter(parts.values()))
    frange = (*ps0[0]["range"], study.quantizer.guard) if mpc.feedback_bits is not None else None
    true = run_closed_loops([(A, B)], A, B, mpc, system, frange)
    cost = float(true.cost[0])
    return out, (cost if np.isfinite(cost) and cost > 0 else None)


def _skipped_row(config: BudgetConfig, b: int, note: str) -> dict[str, Any]:
    _, n, m, _ = config.shape()
    return {
        "bits": b,
        "trajectories": runs_bought(config.total_bits, config.study.steps, n + m, b),
        "samples": runs_bought(config.total_bits, config.study.steps, n + m, b) * config.study.steps,
        "identifiable": False,
        "note": note,
        "err_G": {"mean": None, "std": None},
        "_err": None,
        "_pred": None,
        "meets_target": False,
    }


def _row(
    config: BudgetConfig, b: int, runs: int, ps: list[dict[str, Any]], lp: Any, true_cost: float | None
) -> dict[str, Any]:
    """The row of word length ``b`` from its realizations ``ps`` (and the linear loops ``lp``)."""
    s = config.study
    err = Stats.of([p["err_G"] for p in ps])
    row: dict[str, Any] = {
        "bits": b,
        "trajectories": runs,
        "samples": runs * s.steps,
        "identifiable": True,
        "note": "; ".join(sorted({n for p in ps for n in p["notes"]})),
        "eps": np.mean([p["eps"] for p in ps], axis=0).tolist(),
        "err_G": err.to_dict(),
        "err_A": Stats.of([p["err_A"] for p in ps]).to_dict(),
        "err_B": Stats.of([p["err_B"] for p in ps]).to_dict(),
        "overload_fraction": float(np.mean([p["overload"] for p in ps])),
        "bcls_fallbacks": int(sum(p["fallback"] for p in ps)),
        "ident_failures": int(sum(p["failed"] for p in ps)),
        "_err": err.mean,
        "_pred": None,
    }
    if "theorem1_err_G" in ps[0]:
        row["theorem1_err_G"] = float(np.mean([p["theorem1_err_G"] for p in ps]))
        pred = [p["predicted"] for p in ps if p["predicted"] is not None]
        row["predicted_err_G"] = float(np.mean([v[0] for v in pred])) if pred else None
        row["predicted_bias"] = float(np.mean([v[1] for v in pred])) if pred else None
        row["_pred"] = row["predicted_err_G"]
    row.update(_loop_part(config, ps, lp, true_cost))
    return row


def _loop_part(config: BudgetConfig, ps: list[dict[str, Any]], lp: Any, true_cost: float | None) -> dict[str, Any]:
    """Stabilized share, outcomes, cost gap and whether the target is met (empty without loops)."""
    if config.study.mpc is None:
        return {"meets_target": False}
    if lp is not None:  # linear: the closed loops of every model at this b
        outcome = list(lp.outcome)
        kept = np.isin(np.asarray(outcome), ("converged", "bounded")) if outcome else np.zeros(0, bool)
        cost = Stats.of(lp.cost[kept]).mean if kept.any() else None
        gap = (cost / true_cost - 1.0) if (cost is not None and true_cost) else None
        extra: dict[str, Any] = {"cost_gap": gap}
    else:  # nonlinear: one Koopman loop per realization
        outcome = [p["loop"][0] for p in ps if p["loop"] is not None]
        offs = np.asarray([p["loop"][1] for p in ps if p["loop"] is not None], float)
        offs = offs[np.isfinite(offs)]
        gap = None
        extra = {
            "settled_offset": {"median": float(np.median(offs)), "max": float(np.max(offs))} if offs.size else None,
            "within_radius": int(sum(p["loop"][2] for p in ps if p["loop"] is not None)),
        }
    counts = {k: outcome.count(k) for k in ("converged", "bounded", "diverged", "failed")}
    share = counts["converged"] / len(outcome) if outcome else None
    ok = share is not None and share >= config.target
    if lp is not None:
        ok = ok and gap is not None and abs(gap) <= config.cost_gap
    return {"stabilized_fraction": share, "closed_loop_outcomes": counts, **extra, "meets_target": bool(ok)}
