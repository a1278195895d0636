"""One realization of a budget study (:mod:`~qsid_core.studies.budget`) at every word length, linear or nonlinear.

Each task is module level (picklable for process pools) and runs the sweep's own stages: for a linear plant an
:class:`~qsid_core.studies.experiment.Experiment` per word length with the runs that word length buys, for a
nonlinear one a :class:`~qsid_core.studies.study_nonlinear.KoopmanExperiment` (and its Koopman MPC loops).
A linear realization simulates its runs once, at the largest count any word length buys, and each word length
uses the first runs of them (nested data, as ``qsid datalength`` does): every realization has its own data,
sensor noise and dither, and within a realization the word lengths are compared on common data. The quantizer's
range is that of the realization's whole data set (per channel, or shared, as configured; a fixed range as
given), as a sensor's range does not depend on how many samples are sent: so the recorded data are normalised
once per realization, and each word length's :class:`~qsid_core.studies.experiment.Experiment` is handed its
data, their normalised prefix, their Gram matrices (summed run by run) and their quantized moments, what it would
compute itself for that fixed range, the Gram matrices to rounding (``tests/core/studies/test_budget.py``). The
quantized moments of every word length come from one pass over the data
(:func:`~qsid_core.quantization.quantized_moments` with ``runs``: one stream of dither draws, each word length on
its own prefix, bit for bit what its experiment would draw and sum).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..control import run_koopman_loops
from ..identification.theorem1 import theorem1_prediction
from ..plant.data import Dataset, simulate, with_sensor_noise
from ..plant.systems import get_system
from ..quantization.moments import Moments, prepare, quantized_moments
from ..quantization.quantize import ERROR_VARIANCE, QuantizerSpec, data_ranges
from .budget_model import predicted_error, prefix_moments
from .config import KoopmanConfig, SweepConfig
from .executors import single_threaded_blas
from .experiment import Experiment
from .identification_stage import dither_seeds
from .study_nonlinear import KoopmanExperiment

__all__ = ["Plan", "fixed_range", "linear_realization", "nonlinear_realization", "realization_seeds"]

#: The word lengths a realization computes and the runs each buys: ``((b, runs), ...)``.
Plan = tuple[tuple[int, int], ...]


def realization_seeds(data_seed: int, dither_seed: int, r: int) -> tuple[int, int]:
    """The data and dither seeds of realization ``r`` (drawn from ``(seed, r)``: independent streams)."""
    ds = int(np.random.SeedSequence([data_seed, r]).generate_state(1)[0])
    dt = int(np.random.SeedSequence([dither_seed, r]).generate_state(1)[0])
    return ds, dt


def _rel(M: np.ndarray, G: np.ndarray) -> float:
    return float(np.linalg.norm(M - G) / np.linalg.norm(G))


def _prefix(data: Dataset, runs: int) -> Dataset:
    return Dataset(data.states[:runs], data.inputs[:runs], data.seed, data.input_amplitude)


def fixed_range(recorded: Dataset, q: QuantizerSpec) -> QuantizerSpec:
    """The quantizer ``q`` with its range fixed to that of the ``recorded`` data (a fixed range stays as given)."""
    if q.range_mode == "fixed":
        return q
    lo, hi = data_ranges(recorded.states, recorded.inputs, q)
    return QuantizerSpec(
        dither=q.dither, range_mode="fixed", guard=q.guard, fixed_range=tuple(zip(lo.tolist(), hi.tolist()))
    )


def linear_realization(study: SweepConfig, plan: Plan, r: int) -> list[dict[str, Any]]:
    """Realization ``r`` of a linear budget study: per word length of ``plan`` its model, errors, Theorem 1's
    LS limit and the predicted error (:func:`~qsid_core.studies.budget_model.predicted_error`)."""
    system = get_system(study.system)
    G = system.G
    ds, dt = realization_seeds(study.data_seed, study.dither_seed, r)
    out = []
    with single_threaded_blas():
        full = simulate(system, max(k for _, k in plan), study.steps, ds, study.input_amplitude, study.state_amplitude)
        pp, xp, lag = prefix_moments(full)  # the clean moments of every prefix of runs, summed once
        rec = with_sensor_noise(full, study.noise, ds)  # the states as recorded
        spec = fixed_range(rec, study.quantizer)
        zero = np.zeros(pp.shape[1])
        prep = prepare(rec, spec, Moments(PP=pp[-1], XP=xp[-1], T=full.T, eps=zero))
        S1 = study.steps + 1
        # every word length's quantized moments in one pass over the data, each on its own prefix of runs with
        # the dither stream its experiment would draw (bit for bit, as quantized_moments says)
        rng = np.random.default_rng(dither_seeds(dt, 1)[0]) if spec.dither != "none" else None
        moms = quantized_moments(prep, [b for b, _ in plan], spec, rng, runs=[k for _, k in plan])
        for (b, runs), mom in zip(plan, moms):
            cfg = replace(
                study, quantizer=spec, bits=(b,), trajectories=runs, realizations=1, data_seed=ds, dither_seed=dt,
                mpc=None,
            )  # fmt: skip
            ex = Experiment(cfg)
            data = _prefix(full, runs)
            exact = Moments(PP=pp[runs - 1], XP=xp[runs - 1], T=runs * study.steps, eps=zero)
            mine = replace(prep, yc=prep.yc[: runs * S1], trajectories=runs, exact=exact)
            ex.cache.store([(ex.keys.data(), data), (ex.keys.prepared(), mine), (ex.keys.moments(b), [mom])])
            ident = ex.identification(b)
            A, B = ident.A_hat[0], ident.B_hat[0]
            noise = ex.noise_variance()
            q = cfg.quantizer
            limit = theorem1_prediction(G, ex.Sigma, ident.eps, q.dither, noise)
            row: dict[str, Any] = {
                "bits": b,
                "A": A,
                "B": B,
                "err_G": _rel(np.hstack([A, B]), G),
                "err_A": float(ident.err_A[0]),
                "err_B": float(ident.err_B[0]),
                "theorem1_err_G": _rel(limit, G),
                "overload": float(ident.overload[0]),
                "fallback": bool(ident.fallback[0]),
                "failed": bool(ident.failed[0]),
                "notes": list(ident.notes),
                "eps": ident.eps,
                "range": (ex.prepared.lo, ex.prepared.hi),
                "predicted": None,
            }
            if q.dither == "subtractive":
                qv = ident.eps**2 * ERROR_VARIANCE["subtractive"]
                corrected = (qv + (noise if cfg.noise_known else 0.0)) if cfg.estimator == "bcls" else 0.0 * qv
                row["predicted"] = predicted_error(G, ex.Sigma, lag, qv, noise, corrected, runs * cfg.steps, cfg.steps)
            out.append(row)
    return out


def nonlinear_realization(study: KoopmanConfig, plan: Plan, r: int) -> list[dict[str, Any]]:
    """Realization ``r`` of a nonlinear budget study: per word length of ``plan`` the row of the nonlinear sweep
    (errors against the EDMD of the same unquantized runs) and, with an MPC, its Koopman loop on the true plant."""
    ds, dt = realization_seeds(study.data_seed, study.dither_seed, r)
    out = []
    with single_threaded_blas():
        for b, runs in plan:
            cfg = replace(study, bits=(b,), trajectories=runs, realizations=1, data_seed=ds, dither_seed=dt)
            kx = KoopmanExperiment(cfg)
            km = kx.models(b, cfg.estimator)
            row: dict[str, Any] = {
                "bits": b,
                "err_G": km.row["err_G"]["mean"],
                "err_A": km.row["err_A"]["mean"],
                "err_B": km.row["err_B"]["mean"],
                "overload": km.row["overload_fraction"],
                "fallback": km.row["bcls_fallbacks"] > 0,
                "failed": km.row["ident_failures"] > 0,
                "notes": list(km.row["notes"]),
                "eps": np.asarray(km.row["eps_x"] + km.row["eps_u"]),
                "loop": None,
            }
            if cfg.mpc is not None:
                loops = run_koopman_loops(list(km.models), kx.lifting, kx.system, cfg.mpc, cfg.radius)
                row["loop"] = (loops.outcome[0], float(loops.settled_offset[0]), bool(loops.within_radius[0]))
            out.append(row)
    return out
