"""The signed cost gap of "how many bits" and the closed-loop length chosen from the plant.

:func:`cost_gap` compares a row's mean closed-loop cost with the MPC built on the true model;
:func:`loop_length` picks the number of steps over which that comparison is not an artefact of
stopping early (see :mod:`qsid_core.studies.bits`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import ConfigError
from .experiment import Experiment

__all__ = ["LOOP_COST_TOLERANCE", "LOOP_TIME_CONSTANTS", "cost_gap", "loop_length"]

#: The loop length chosen from the plant: the true-model loop's cost after it is at most this share of its total.
LOOP_COST_TOLERANCE = 1e-6
#: ... searched over this many slowest time constants of the true-model loop (at most 10000 steps).
LOOP_TIME_CONSTANTS = 20


def cost_gap(row: Mapping[str, Any], true_cost: float | None) -> float | None:
    """``mean closed-loop cost / true-model cost - 1`` of one summary row, signed.

    Over the loops judged converged or bounded (``mpc_cost["mean_bounded"]``); rows without it
    (older results) use the plain mean, and only when no loop diverged or failed.

    Parameters
    ----------
    row : mapping
        One summary row (``closed_loop_outcomes``, ``mpc_cost``).
    true_cost : float or None
        Closed-loop cost of the MPC built on the true model.

    Returns
    -------
    float or None
        None when there is no cost to compare (or no true-model cost).
    """
    oc = row.get("closed_loop_outcomes") or {}
    mc = row.get("mpc_cost") or {}
    if "mean_bounded" in mc:
        cost = mc["mean_bounded"]
    else:
        cost = mc.get("mean") if not (oc.get("diverged") or oc.get("failed")) else None
    return (cost / true_cost - 1.0) if (cost is not None and true_cost) else None


def loop_length(ex: Experiment) -> dict[str, Any]:
    """The closed-loop length chosen from the plant: ``{"steps": N, "rule": text}``.

    The MPC built on the true model is run for :data:`LOOP_TIME_CONSTANTS` slowest time constants
    of its linear law (``-1 / ln rho(A - B K)`` steps, at most 10000); ``N`` is the first step
    after which its remaining cost is at most :data:`LOOP_COST_TOLERANCE` of its total, so the
    cost gap is not an artefact of stopping early. Kept as configured, with the reason, when the
    true-model loop cannot settle (a disturbance, sensor noise, a quantized measurement, a
    time-varying reference, or the true-model loop itself not converging).
    """
    cfg = ex.config.mpc
    if cfg is None:
        raise ConfigError("the loop length needs the MPC (mpc must not be None)")
    if cfg.disturbance or cfg.feedback_noise or cfg.feedback_bits is not None or cfg.reference is not None:
        return {"steps": cfg.steps, "rule": f"{cfg.steps} steps as configured (the loop does not settle to a point)"}
    radii = ex.true_model_loop().spectral_radius
    rho = float(radii[0]) if radii is not None else math.nan
    if not (0.0 <= rho < 1.0):
        return {"steps": cfg.steps, "rule": f"{cfg.steps} steps as configured (the true-model loop is not stable)"}
    tau = -1.0 / math.log(rho) if rho > 0 else 1.0
    scan = int(min(10000, max(cfg.horizon, math.ceil(LOOP_TIME_CONSTANTS * tau))))
    lp = ex.with_config(dataclasses.replace(ex.config, mpc=dataclasses.replace(cfg, steps=scan))).true_model_loop()
    w = cfg.resolve(ex.system)
    e = lp.states[0, :-1] - np.asarray(lp.x_ref, dtype=float).reshape(-1, ex.system.n)[:scan]
    u = lp.inputs[0]
    stage = np.einsum("ti,ij,tj->t", e, w.Q, e) + np.einsum("ti,ij,tj->t", u, w.R, u)
    if not np.all(np.isfinite(stage)) or not stage.sum() > 0:
        return {"steps": cfg.steps, "rule": f"{cfg.steps} steps as configured (the true-model cost is not finite)"}
    tail = np.cumsum(stage[::-1])[::-1]  # tail[t]: cost from step t on
    steps = int(np.argmax(tail <= LOOP_COST_TOLERANCE * tail[0])) if tail[-1] <= LOOP_COST_TOLERANCE * tail[0] else scan
    steps = max(steps, 1)
    return {
        "steps": steps,
        "rule": f"{steps} steps: the true-model loop's remaining cost is below {LOOP_COST_TOLERANCE:g} of its total "
        f"(slowest time constant {tau:.3g} steps; searched over {scan})",
    }
