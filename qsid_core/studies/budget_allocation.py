"""Per-channel allocation: ``bits_per_sample`` bits per sample over the ``n + m`` channels, split where they count.

The budget of :mod:`~qsid_core.studies.budget` buys ``floor(T / (S B))`` runs of ``S`` steps when every sample
carries ``B`` bits over all channels, whatever their split. The split changes the cell width ``eps_i`` of each
channel, hence ``d_i = eps_i^2 / 12`` and the predicted error of :func:`~qsid_core.studies.budget_model.
predicted_error`. The proposal minimises that predicted error over integer splits (at least one bit, at most 32
per channel): greedily, one bit at a time to the channel whose bit lowers the prediction most, then moving single
bits between channels while that lowers it. Where the prediction is linear in the ``d_i``
(``err^2 ~ sum_i w_i d_i``, the variance-dominated regime of BCLS) this is reverse water-filling: each channel gets
bits until its weighted distortion ``w_i d_i`` reaches a common level (the derivation: ``docs/science.rst``).

The prediction needs the plant's ``[A, B]`` (the design-time model; qsid uses the plant's own) and the data's
moments and ranges, taken from a pilot data set of the same size drawn from its own seed (independent of every
realization measured). The proposal and the uniform split (``B // (n + m)`` each, the remainder one bit more to
the first channels, states first) are then measured on ``realizations`` data sets, each with its own data, sensor
noise and dither and both splits on the same ones (a paired comparison).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..plant.systems import get_system
from ..quantization.quantize import ERROR_VARIANCE, MAX_BITS, channel_eps
from .budget import BudgetConfig, runs_bought
from .budget_model import lag_moment, predicted_error
from .budget_tasks import realization_seeds
from .config import SweepConfig
from .executors import InlineExecutor, single_threaded_blas
from .experiment import Experiment
from .summary import Stats, json_clean

__all__ = ["AllocationResult", "propose_allocation", "run_allocation", "uniform_allocation"]

#: The pilot data set's seed stream: ``SeedSequence([data_seed, PILOT_STREAM])``, apart from every realization's.
PILOT_STREAM = 2**31 - 1

Split = tuple[int, ...]


def uniform_allocation(total: int, channels: int) -> Split:
    """``total`` bits over ``channels`` as equal as can be: ``total // channels`` each, one more to the first ones."""
    q, r = divmod(total, channels)
    return tuple(q + (1 if i < r else 0) for i in range(channels))


def propose_allocation(cost: Callable[[Split], float], total: int, channels: int) -> Split:
    """The integer split of ``total`` bits (1..32 per channel) that ``cost`` finds least: greedy, then single moves.

    ``cost`` is the predicted error of a split. Greedy: from one bit each, every further bit goes to the channel
    whose bit lowers ``cost`` most; then a bit moves from one channel to another while that lowers it.
    """
    alloc = [1] * channels
    for _ in range(total - channels):
        trials = [(cost(tuple(alloc[:i] + [alloc[i] + 1] + alloc[i + 1 :])), i) for i in range(channels)]
        _, best = min(t for t in trials if alloc[t[1]] < MAX_BITS)
        alloc[best] += 1
    here = cost(tuple(alloc))
    for _ in range(total * channels):  # each move lowers the cost: this ends, and well before the cap
        moves = []
        for i in range(channels):
            for j in range(channels):
                if i != j and alloc[i] > 1 and alloc[j] < MAX_BITS:
                    trial = list(alloc)
                    trial[i] -= 1
                    trial[j] += 1
                    moves.append((cost(tuple(trial)), trial))
        if not moves:
            break
        c, trial = min(moves, key=lambda t: t[0])
        if not c < here * (1 - 1e-12):
            break
        alloc, here = trial, c
    return tuple(alloc)


def _study(config: BudgetConfig) -> tuple[SweepConfig, int]:
    s = config.study
    assert isinstance(s, SweepConfig) and config.bits_per_sample is not None
    runs = runs_bought(config.total_bits, s.steps, 1, config.bits_per_sample)
    _, n, m, unknowns = config.shape()
    if runs < 1 or runs * s.steps < unknowns:
        raise ConfigError(
            f"total bits: {config.total_bits:g} bits at {config.bits_per_sample} bits per sample buy {runs} run(s) "
            f"of {s.steps} steps, fewer samples than the {unknowns} unknowns per row; use a larger budget"
        )
    if runs > 100_000:
        raise ConfigError(f"total bits: {config.total_bits:g} bits buy {runs} runs, more than 100000; use longer runs")
    return replace(s, system=get_system(s.system), trajectories=runs, realizations=1, mpc=None, bits=(1,)), runs


def _with_split(study: SweepConfig, split: Split, ds: int, dt: int) -> SweepConfig:
    n = study.system.n if not isinstance(study.system, str) else get_system(study.system).n
    return replace(study, state_bits=split[:n], input_bits=split[n:], data_seed=ds, dither_seed=dt)


def _corrected(study: SweepConfig, qv: np.ndarray, noise: np.ndarray) -> np.ndarray:
    if study.estimator != "bcls":
        return np.zeros_like(qv)
    return qv + (noise if study.noise_known else 0.0)


def allocation_cost(study: SweepConfig) -> Callable[[Split], float]:
    """The predicted error of a split on ``study``'s pilot data set (its seed :data:`PILOT_STREAM`'s)."""
    ds = int(np.random.SeedSequence([study.data_seed, PILOT_STREAM]).generate_state(1)[0])
    ex = Experiment(replace(study, data_seed=ds))
    G, Sigma, lag = ex.system.G, ex.Sigma, lag_moment(ex.data)
    noise = ex.noise_variance()
    lo, hi = ex.prepared.lo, ex.prepared.hi
    q = study.quantizer
    T, S = study.trajectories * study.steps, study.steps

    def cost(split: Split) -> float:
        qv = channel_eps(lo, hi, split, q.guard, q.dither) ** 2 * ERROR_VARIANCE["subtractive"]
        return predicted_error(G, Sigma, lag, qv, noise, _corrected(study, qv, noise), T, S)[0]

    return cost


def allocation_realization(study: SweepConfig, splits: tuple[Split, ...], r: int) -> list[dict[str, Any]]:
    """Realization ``r``: every split identified on the same data, sensor noise and dither; its error and prediction."""
    ds, dt = realization_seeds(study.data_seed, study.dither_seed, r)
    out = []
    with single_threaded_blas():
        ex: Experiment | None = None
        for split in splits:
            cfg = _with_split(study, split, ds, dt)
            ex = Experiment(cfg) if ex is None else ex.with_config(cfg)  # the data simulated once
            ident = ex.identification(1)
            A, B = ident.A_hat[0], ident.B_hat[0]
            G = ex.system.G
            noise = ex.noise_variance()
            qv = ident.eps**2 * ERROR_VARIANCE["subtractive"]
            pred = predicted_error(
                G, ex.Sigma, lag_moment(ex.data), qv, noise, _corrected(cfg, qv, noise), cfg.trajectories * cfg.steps,
                cfg.steps,
            )  # fmt: skip
            out.append(
                {
                    "err_G": float(np.linalg.norm(np.hstack([A, B]) - G) / np.linalg.norm(G)),
                    "predicted": pred[0],
                    "eps": np.asarray(ident.eps, float),
                    "failed": bool(ident.failed[0]),
                }
            )
    return out


@dataclass
class AllocationResult:
    """The proposed split against the uniform one (:meth:`to_dict` is the JSON ``qsid budget --bits-per-sample``
    prints)."""

    config: BudgetConfig
    system: str
    channels: tuple[str, ...]
    runs: int
    splits: dict[str, Split]
    predicted: dict[str, float]
    measured: dict[str, list[dict[str, Any]]]
    timing_s: float = 0.0

    def ratios(self) -> np.ndarray:
        """Per realization, the proposal's error over the uniform split's (paired: same data, noise and dither)."""
        p = np.asarray([v["err_G"] for v in self.measured["proposed"]], float)
        u = np.asarray([v["err_G"] for v in self.measured["uniform"]], float)
        out: np.ndarray = p / u
        return out

    def to_dict(self) -> dict[str, Any]:
        c, s = self.config, self.config.study
        assert isinstance(s, SweepConfig)
        ratio = self.ratios()

        def split(name: str) -> dict[str, Any]:
            ms = self.measured[name]
            return {
                "bits": list(self.splits[name]),
                "eps": np.mean([v["eps"] for v in ms], axis=0).tolist(),
                "predicted_err_G": self.predicted[name],
                "err_G": Stats.of([v["err_G"] for v in ms]).to_dict(),
                "ident_failures": int(sum(v["failed"] for v in ms)),
            }

        out: dict[str, Any] = json_clean(
            {
                "kind": "budget-allocation",
                "system": self.system,
                "config": {
                    "total_bits": c.total_bits,
                    "bits_per_sample": c.bits_per_sample,
                    "steps": s.steps,
                    "realizations": s.realizations,
                    "estimator": s.estimator,
                    "dither": s.quantizer.dither,
                    "range": s.quantizer.range_mode,
                    "guard": s.quantizer.guard,
                    "noise": list(s.noise),
                    "noise_known": s.noise_known,
                    "data_seed": s.data_seed,
                    "dither_seed": s.dither_seed,
                },
                "channels": list(self.channels),
                "trajectories": self.runs,
                "samples": self.runs * s.steps,
                "uniform": split("uniform"),
                "proposed": split("proposed"),
                "ratio": {**Stats.of(ratio).to_dict(), "median": float(np.median(ratio))},
                "proposed_better": int(np.sum(ratio < 1.0)),
                "timing_s": {"total": round(self.timing_s, 4)},
            }
        )
        return out


Progress = Callable[[int, int, str], None]


def run_allocation(
    config: BudgetConfig, executor: Executor | None = None, progress: Progress | None = None
) -> AllocationResult:
    """Propose a split of ``config.bits_per_sample`` over the channels and measure it against the uniform one.

    Raises
    ------
    ConfigError
        ``bits_per_sample`` unset, or a budget that buys fewer samples than unknowns at that many bits per sample.
    """
    if not isinstance(config, BudgetConfig) or config.bits_per_sample is None:
        raise ConfigError("bits per sample: give the bits per sample over all channels for an allocation study")
    t0 = time.perf_counter()
    study, runs = _study(config)
    system = study.system
    assert not isinstance(system, str)
    p = system.n + system.m
    cost = allocation_cost(study)
    splits = {
        "uniform": uniform_allocation(config.bits_per_sample, p),
        "proposed": propose_allocation(cost, config.bits_per_sample, p),
    }
    pool = executor or InlineExecutor()
    pair = (splits["uniform"], splits["proposed"])
    futs = [pool.submit(allocation_realization, study, pair, r) for r in range(config.study.realizations)]
    per = []
    for i, f in enumerate(futs):
        per.append(f.result())
        if progress:
            progress(i + 1, len(futs), "realizations")
    measured = {"uniform": [v[0] for v in per], "proposed": [v[1] for v in per]}
    predicted = {k: float(np.mean([v["predicted"] for v in measured[k]])) for k in splits}
    names = tuple(system.state_names) + tuple(system.input_names)
    return AllocationResult(config, system.name, names, runs, splits, predicted, measured, time.perf_counter() - t0)
