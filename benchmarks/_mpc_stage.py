"""The saturated MPC stage of a Boeing 747 sweep: the compiled closed loop against per-step OSQP loops.

Every model identified from quantized data (Boeing 747, ``trajectories x steps`` of
random-input data, word lengths ``bits``, ``realizations`` subtractive-dither
realizations each) runs the letter's MPC (horizon 10, 50 steps) in closed loop on
the true plant with ``|u| <= 0.3`` from ``x0 = 20 * [1, 1, 0, 0]``, so the input
bound is active on nearly every step. Timed side by side, interleaved, best and
median of ``repeats`` (the per-step OSQP loops fewer times):

* ``naive per-step OSQP loop``: one model at a time, the sparse QP set up once per
  model and OSQP warm-started at every step (``bench_sweep.naive_closed_loop``);
* ``engine, solver=osqp``: :func:`run_closed_loops` with the previous engine's OSQP path;
* ``engine, batched active set``: the default engine with the compiled loop switched
  off (the fast path ahead in numpy batches, the constrained steps' box QPs batched);
* ``engine, compiled loop``: the default (:mod:`qsid_core.control.loop_kernel`).

All four include building the controllers (DARE, gains, QP setup); no verdicts
(``verify_steps=None``; the last row adds them to show their cost). Agreement: max
``|u - u_osqp|`` over all applied inputs of the loops that ran.
"""

from __future__ import annotations

import os
import statistics
import time

import numpy as np

import qsid_core.control.closed_loop as closed_loop
from qsid_core import Experiment, MPCConfig, SweepConfig, run_closed_loops

SATURATED = dict(u_max=0.3, x0=(20.0, 20.0, 0.0, 0.0), horizon=10, steps=50)
PAPER = dict(trajectories=200, steps=1000, bits=tuple(range(1, 17)))
QUICK = dict(trajectories=20, steps=200, bits=(2, 6, 10, 14))
ROWS = (
    "naive per-step OSQP loop",
    "engine, solver=osqp",
    "engine, batched active set",
    "engine, compiled loop",
    "engine, compiled loop + verdicts",
)
OSQP_ROWS = ROWS[:2]


def models(quick: bool, realizations: int):
    """The identified Boeing models of every (b, realization) and the system."""
    scale = QUICK if quick else PAPER
    ex = Experiment(SweepConfig(system="boeing747", mpc=None, realizations=realizations, **scale))
    return [mdl for b in scale["bits"] for mdl in ex.identification(b).models], ex.system


def _naive(mdls, s, cfg):
    from bench_sweep import naive_closed_loop

    w = cfg.resolve(s)
    us = np.full((len(mdls), cfg.steps, s.m), np.nan)
    for i, (Ah, Bh) in enumerate(mdls):
        _, us[i], _ = naive_closed_loop(Ah, Bh, s.A, s.B, w, cfg)
    return us


def _runner(row: str, mdls, s):
    cfg = MPCConfig(**SATURATED, verify_steps=None)
    if row == ROWS[0]:
        return lambda: _naive(mdls, s, cfg)
    if row == ROWS[1]:
        return lambda: run_closed_loops(mdls, s.A, s.B, MPCConfig(**SATURATED, verify_steps=None, solver="osqp"), s)
    if row == ROWS[2]:

        def batched():
            real = closed_loop.eligible
            closed_loop.eligible = lambda loops: False
            try:
                return run_closed_loops(mdls, s.A, s.B, cfg, s)
            finally:
                closed_loop.eligible = real

        return batched
    if row == ROWS[3]:
        return lambda: run_closed_loops(mdls, s.A, s.B, cfg, s)
    return lambda: run_closed_loops(mdls, s.A, s.B, MPCConfig(**SATURATED), s)


def stage(quick: bool, realizations: int, repeats: int, osqp_repeats: int) -> dict:
    """Time every row on the same models; returns the figures and the agreement."""
    mdls, s = models(quick, realizations)
    runs = {r: _runner(r, mdls, s) for r in ROWS}
    run_closed_loops(mdls[:4], s.A, s.B, MPCConfig(**SATURATED), s)  # compiled kernels loaded, not timed
    times: dict = {r: [] for r in ROWS}
    load: dict = {r: [] for r in ROWS}
    inputs: dict = {}
    qp_steps = 0
    for k in range(max(repeats, osqp_repeats)):
        for r in ROWS:
            if k >= (osqp_repeats if r in OSQP_ROWS else repeats):
                continue
            load[r].append(os.getloadavg()[0])
            t0 = time.perf_counter()
            res = runs[r]()
            times[r].append(time.perf_counter() - t0)
            inputs[r] = res if isinstance(res, np.ndarray) else res.inputs
            if r == ROWS[3]:
                qp_steps = res.qp_steps
    ref = inputs[ROWS[1]]
    ok = np.isfinite(ref).all(axis=(1, 2))
    out = dict(loops=len(mdls), qp_steps=qp_steps, loop_steps=len(mdls) * SATURATED["steps"], rows={})
    best_c = min(times[ROWS[3]])
    for r in ROWS:
        du = np.abs(inputs[r][ok] - ref[ok])
        out["rows"][r] = dict(
            best_s=min(times[r]),
            median_s=statistics.median(times[r]),
            times_s=times[r],
            loadavg_1min=load[r],
            max_abs_du_vs_osqp=float(np.nanmax(du)) if du.size else 0.0,
            time_over_compiled=min(times[r]) / best_c,
        )
    out["speedup_vs_naive_osqp"] = out["rows"][ROWS[0]]["best_s"] / best_c
    out["speedup_vs_engine_osqp"] = out["rows"][ROWS[1]]["best_s"] / best_c
    out["speedup_vs_batched"] = out["rows"][ROWS[2]]["best_s"] / best_c
    return out


def report(r: dict, tol: float) -> bool:
    """Print the section; returns whether every row agrees with the OSQP loops to ``tol``."""
    print(
        f"\nsaturated stage: {r['loops']} identified Boeing 747 models x {SATURATED['steps']} steps, |u| <= 0.3, "
        f"x0 = 20*[1,1,0,0]; {r['qp_steps']} of {r['loop_steps']} steps constrained"
    )
    print(
        f"  {'':<36}{'best [ms]':>11}{'median [ms]':>13}{'time / compiled':>17}{'max|du| vs osqp':>17}"
        f"{'load (1 min)':>14}"
    )
    agree = True
    for name, v in r["rows"].items():
        agree &= v["max_abs_du_vs_osqp"] <= tol
        lo, hi = min(v["loadavg_1min"]), max(v["loadavg_1min"])
        print(
            f"  {name:<36}{v['best_s'] * 1e3:>11.1f}{v['median_s'] * 1e3:>13.1f}{v['time_over_compiled']:>16.1f}x"
            f"{v['max_abs_du_vs_osqp']:>17.1e}{lo:>8.1f}-{hi:<5.1f}"
        )
    print(
        f"  compiled loop vs naive per-step OSQP: {r['speedup_vs_naive_osqp']:.0f}x, vs the engine's OSQP path "
        f"{r['speedup_vs_engine_osqp']:.0f}x (target >= 100x: "
        f"{'MET' if min(r['speedup_vs_naive_osqp'], r['speedup_vs_engine_osqp']) >= 100 else 'NOT met'}); "
        f"vs the batched active set {r['speedup_vs_batched']:.1f}x; inputs agree to {tol:g}: {'yes' if agree else 'NO'}"
    )
    return agree
