#!/usr/bin/env python
"""A budget study at paper scale against the sweep at the same largest data size, in one run.

The science (issue 39): a sensor link carries ``T`` bits; at word length b it buys ``floor(T / (S (n + m) b))``
runs of ``S`` steps. :func:`qsid_core.studies.run_budget` identifies, at each of 16 word lengths, the data set b
buys, 20 times, each realization with its own data, sensor noise and dither, and runs the MPC of every model on
the true plant. The sweep it is compared with (:func:`qsid_core.run_sweep`) quantizes the data set of the
*largest* budget data size (the runs b = 1 buys) at the same 16 word lengths with 20 dither realizations, and
runs the same loops. Both run on the same executor (two threads, as ``qsid`` runs by default), one after the
other, so a machine's load weighs on both alike; the ratio is printed, of wall time and of the process's CPU time
(on a shared, loaded machine the CPU ratio is the steadier of the two).

Defaults: the Boeing 747, runs of 100 steps, b = 1..16, 20 realizations, BCLS, sensor noise 0.1 known to BCLS,
the default MPC; ``--total-bits`` 4e6 (about a minute each here; the issue's 4e7 takes ten times longer).
``--quick`` is a seconds-long smoke run. The last line is ``RESULT {json}``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from qsid_core import SweepConfig, get_system, run_sweep  # noqa: E402
from qsid_core.studies import BudgetConfig, run_budget, runs_bought  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--system", default="boeing747")
    p.add_argument("--total-bits", type=float, default=4e6)
    p.add_argument("--steps", type=int, default=100)
    p.add_argument("--realizations", type=int, default=20)
    p.add_argument("--bits", default="1:16")
    p.add_argument("--no-mpc", action="store_true")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--quick", action="store_true", help="1e5 bits, 4 word lengths, 3 realizations")
    a = p.parse_args(argv)
    if a.quick:
        a.total_bits, a.bits, a.realizations = 1e5, "2,4,8,16", 3
    study = SweepConfig(
        system=a.system, bits=a.bits, steps=a.steps, realizations=a.realizations, estimator="bcls", noise=0.1,
        noise_known=True, **({"mpc": None} if a.no_mpc else {}),
    )  # fmt: skip
    s = get_system(a.system)
    largest = runs_bought(a.total_bits, a.steps, s.n + s.m, study.bits[0])
    sweep = SweepConfig(**{**{f: getattr(study, f) for f in study.__dataclass_fields__}, "trajectories": largest})
    print(
        f"{a.system}: budget {a.total_bits:g} bits, runs of {a.steps} steps, b = {study.bits[0]}..{study.bits[-1]} "
        f"({len(study.bits)} word lengths), {a.realizations} realizations, MPC {'off' if a.no_mpc else 'on'}, "
        f"{a.threads} threads; the sweep at the largest data size: {largest} runs x {a.steps} steps",
        flush=True,
    )
    with ThreadPoolExecutor(a.threads) as pool:
        t0, c0 = time.perf_counter(), time.process_time()
        res = run_budget(BudgetConfig(a.total_bits, study), pool)
        t_budget, c_budget = time.perf_counter() - t0, time.process_time() - c0
        t0, c0 = time.perf_counter(), time.process_time()
        run_sweep(sweep, pool, tasks=2 * a.threads)
        t_sweep, c_sweep = time.perf_counter() - t0, time.process_time() - c0
    d = res.to_dict()
    print(f"budget study: {t_budget:.1f} s, CPU {c_budget:.1f} s (b_best {d['b_best']}, b_knee {d['b_knee']})")
    print(f"sweep at {largest} x {a.steps}: {t_sweep:.1f} s, CPU {c_sweep:.1f} s")
    print(f"ratio budget / sweep: {t_budget / t_sweep:.2f} (CPU {c_budget / c_sweep:.2f})")
    result = {
        "system": a.system,
        "total_bits": a.total_bits,
        "steps": a.steps,
        "bits": list(study.bits),
        "realizations": a.realizations,
        "mpc": not a.no_mpc,
        "largest_runs": largest,
        "budget_s": round(t_budget, 4),
        "sweep_s": round(t_sweep, 4),
        "ratio": round(t_budget / t_sweep, 3),
        "budget_cpu_s": round(c_budget, 4),
        "sweep_cpu_s": round(c_sweep, 4),
        "cpu_ratio": round(c_budget / c_sweep, 3),
        "b_best": d["b_best"],
        "b_knee": d["b_knee"],
    }
    print("RESULT " + json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
