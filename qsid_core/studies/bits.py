"""How many bits does the controller need? Three word lengths from one sweep.

For each b of a sweep: the share of closed loops that converge on the true plant
(:mod:`qsid_core.control.verdicts`) with a 95 % Wilson interval, and the gap of the
mean closed-loop cost to the MPC built on the true model. From those rows:

``b_observed``
    The smallest b from which on (every larger b of the sweep too) at least
    ``target`` of the loops are stabilized and the mean cost gap is at most
    ``cost_gap`` in absolute value.
``b_robust``
    The smallest b from which on a *sufficient* condition certifies the loops.
    With ``(A^, B^)`` a model and ``K^`` the gain of the MPC built on it (its
    unconstrained law), the small-gain theorem gives stability of ``A - B K^`` when
    ``||(A - A^) - (B - B^) K^||_2 < r_C(A^ - B^ K^)``, the complex stability radius of the
    nominal loop (:func:`qsid_core.control.stability_radius.small_gain_margin`). A b is certified

    * for **Theorem 1's model** (its large-data limit of LS at that b) when the test
      holds with the margin :data:`CERTIFY_TOLERANCE` (``(1 + tol) ||.|| < r_C``) *and* its
      hypotheses are checked on the data: the data's second moments have a limit and the
      dither a known error variance (:mod:`qsid_core.studies.assumptions`), and the
      measured mean relative errors of A^ and B^ are both within ``CERTIFY_TOLERANCE``
      (25 %) of Theorem 1's (in finite data,
      where the fluctuation dominates, or with BCLS, they are not, and a certificate
      for a model the data do not give would be no certificate); or
    * for **every loop's own model**: the test holds for each realization's model and
      gain (no large-data hypothesis; ``robust_realized`` equals the loops run).

    Otherwise the row says "not certified: <why, with the numbers>". Both assume the
    constraints inactive near the reference (the MPC is its linear law there).
``b_letter``
    The smallest b from which on the letter's ultimate bound is self-consistent
    (``delta < rho``: its proof assumes the state stays within ``rho``) and
    informative (``delta < ||x0||``).

Each is None when no b of the sweep qualifies.

The modules: :mod:`~qsid_core.studies.bits_answer` (the rows, the three word lengths, the sentence),
:mod:`~qsid_core.studies.bits_certificate` (the small-gain certificate and its hypotheses),
:mod:`~qsid_core.studies.bits_cost` (the signed cost gap and the loop length chosen from the plant);
this one runs the sweep and puts them together (:func:`bits_needed`).
"""

from __future__ import annotations

import dataclasses
from concurrent.futures import Executor
from typing import Any

from ..control.controllability import data_rate_bits
from ..errors import ConfigError
from .bits_answer import BitsAnswer, answer_from_rows, check_targets
from .bits_certificate import predicted_small_gains, realized_small_gain
from .bits_cost import loop_length
from .config import SweepConfig
from .experiment import Experiment, Progress
from .sweep import run_sweep

__all__ = ["bits_needed"]


def bits_needed(
    config: SweepConfig,
    *,
    target: float = 0.95,
    cost_gap: float = 0.01,
    executor: Executor | None = None,
    progress: Progress | None = None,
    experiment: Experiment | None = None,
    realized: bool = True,
    auto_length: bool = False,
) -> BitsAnswer:
    """Run the sweep of ``config`` and answer "how many bits?" (see the module docstring).

    Parameters
    ----------
    config : SweepConfig
        Needs MPC on (``config.mpc`` not None) and the verdicts (``mpc.verify_steps`` not None).
    target : float in (0, 1]
        Share of stabilized loops ``b_observed`` asks for (default 0.95).
    cost_gap : float >= 0
        Largest relative gap of the mean cost to the true model's (default 0.01).
    executor, progress, experiment
        As in :func:`qsid_core.studies.sweep.run_sweep`.
    realized : bool
        Also count per b the realizations the small-gain test certifies with their own error
        (without it, only Theorem 1's model can certify a b).
    auto_length : bool
        Run the loops for the length chosen from the plant (:func:`qsid_core.studies.bits_cost.loop_length`) instead of
        ``config.mpc.steps``.

    Raises
    ------
    ConfigError
        Bad ``target``/``cost_gap``, MPC off, or verdicts off.
    """
    target, cost_gap = check_targets(target, cost_gap)
    if config.mpc is None:
        raise ConfigError("bits needs the MPC closed loops (mpc must not be None)")
    if config.mpc.verify_steps is None:
        raise ConfigError("bits needs the closed-loop verdicts (verify_steps must not be None)")
    ex = experiment.with_config(config) if experiment is not None else Experiment(config, executor)
    if executor is not None:
        ex.executor = executor
    length: dict[str, Any] = (
        loop_length(ex)
        if auto_length
        else {"steps": config.mpc.steps, "rule": f"{config.mpc.steps} steps as configured"}
    )
    if int(length["steps"]) != config.mpc.steps:
        config = dataclasses.replace(config, mpc=dataclasses.replace(config.mpc, steps=int(length["steps"])))
        ex = ex.with_config(config)
    res = run_sweep(config, executor=executor, progress=progress, experiment=ex)
    robust = predicted_small_gains(ex, res.bits)
    rr = None
    if realized:
        rr = {
            b: int(realized_small_gain(res.identification[b], res.loops[b], res.system.A, res.system.B).sum())
            for b in res.bits
        }
    true_cost = float(res.true_loop.cost[0]) if res.true_loop is not None else None
    settings = res.to_dict()["config"]
    ans = answer_from_rows(
        res.system.name,
        settings,
        [res.summary(b) for b in res.bits],
        true_cost,
        robust=robust,
        robust_realized=rr,
        target=target,
        cost_gap=cost_gap,
        data_rate=data_rate_bits(res.system.A),
        loop_length=length,
    )
    return dataclasses.replace(ans, result=res)
