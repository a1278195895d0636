#!/usr/bin/env python
"""The speed targets of issue 9, measured side by side in one run (ratios, never timed unit tests).

1. **Saturated MPC stage**: Boeing 747, ``|u| <= 0.3``, ``x0 = 20 * [1, 1, 0, 0]``,
   horizon 10, 50 steps, for every model of a Boeing sweep (paper scale: 16 word
   lengths x 50 realizations = 800 loops): :func:`run_closed_loops` with the new
   default (batched active set / DAQP on the condensed QP) against the previous
   engine (``solver="osqp"``), interleaved. Target: >= 25x.
2. **Identification per (b, realization)**, dc-motor paper scale (200 x 1000):
   the engine (quantized moments + LS + errors) against the fused kernel alone
   (:func:`qsid_core.quantization.kernels.accumulate_chunk` on pre-drawn dither: the floor),
   and the numpy reference. Target: engine <= 1.5x the floor.
3. **numba costs**: ``import numba``, first call with an empty cache (compile),
   first call in a fresh process with the cache filled (load), each in a new process.
4. **Paper-scale ``qsid sweep``** (dc-motor, MPC on), one process, wall clock from
   process start, with the compiled kernels and with ``QSID_NO_NUMBA=1``. Target: <= 2.5 s.

Figures are measured, best and median of ``--repeats``; the last line is ``RESULT {json}``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np

from qsid_core import Experiment, MPCConfig, SweepConfig, identify, quantized_moments, relative_errors, run_closed_loops
from qsid_core.quantization import CHUNK_ROWS, kernels

PAPER = dict(trajectories=200, steps=1000, realizations=50, bits=tuple(range(1, 17)))
QUICK = dict(trajectories=20, steps=200, realizations=4, bits=(2, 6, 10, 14))
SATURATED = dict(u_max=0.3, x0=(20.0, 20.0, 0.0, 0.0), horizon=10, steps=50)


def _stats(ts: list) -> dict:
    return dict(best=min(ts), median=statistics.median(ts), times=ts)


def saturated_mpc(scale: dict, repeats: int, osqp_repeats: int) -> dict:
    """Section 1: the saturated Boeing MPC stage, new engine against the previous OSQP engine."""
    ex = Experiment(SweepConfig(system="boeing747", mpc=None, **scale))
    models = [mdl for b in scale["bits"] for mdl in ex.identification(b).models]
    s = ex.system
    new, old = MPCConfig(**SATURATED), MPCConfig(**SATURATED, solver="osqp")
    run_closed_loops(models[:4], s.A, s.B, new, s)  # compile / warm up
    tn, to, a, b = [], [], None, None
    for k in range(max(repeats, osqp_repeats)):
        if k < repeats:
            t0 = time.perf_counter()
            a = run_closed_loops(models, s.A, s.B, new, s)
            tn.append(time.perf_counter() - t0)
        if k < osqp_repeats:
            t0 = time.perf_counter()
            b = run_closed_loops(models, s.A, s.B, old, s)
            to.append(time.perf_counter() - t0)
    ok = ~(a.failed | b.failed)
    return dict(
        loops=len(models),
        qp_steps=a.qp_steps,
        qp_steps_osqp=b.qp_steps,
        failed=int(a.failed.sum()),
        failure_mismatches=int((a.failed != b.failed).sum()),
        max_abs_du=float(np.abs(a.inputs[ok] - b.inputs[ok]).max()),
        max_rel_dcost=float(np.abs(a.cost[ok] - b.cost[ok]).max() / np.abs(b.cost[ok]).max()),
        new=_stats(tn),
        old=_stats(to),
        speedup=min(to) / min(tn),
    )


def _kernel_floor(prep, bits, spec, seeds) -> float:
    """Seconds of the fused kernel alone (dither drawn beforehand, not timed) over the given realizations."""
    yc = prep.yc
    N, p = yc.shape
    S1 = prep.steps + 1
    half = np.array([2.0 ** (b - 1) for b in bits])
    scale = np.array([2.0**b for b in bits])
    total = 0.0
    for ss in seeds:
        rng = np.random.default_rng(ss)
        draws = [rng.uniform(-0.5, 0.5, size=yc[s : s + CHUNK_ROWS].shape) for s in range(0, N, CHUNK_ROWS)]
        nb = len(bits)
        M, C, sums = np.zeros((nb, p, p)), np.zeros((nb, p, prep.n)), np.zeros((nb, p))
        over, prev = np.zeros(nb, dtype=np.int64), np.zeros((nb, p))
        vl, vf = np.zeros((nb, prep.trajectories, p)), np.zeros((nb, prep.trajectories, p))
        t0 = time.perf_counter()
        for k, s in enumerate(range(0, N, CHUNK_ROWS)):
            kernels.accumulate_chunk(
                yc[s : s + CHUNK_ROWS], draws[k], scale, half, s, S1, M, C, sums, over, prev, vl, vf
            )
        total += time.perf_counter() - t0
    return total


def identification(scale: dict, repeats: int, realizations: int) -> dict:
    """Section 2: identification per (b, realization), engine vs fused-kernel floor vs numpy reference."""
    ex = Experiment(SweepConfig(system="dc-motor", mpc=None, **scale))
    prep, spec, bits = ex.prepared, ex.config.quantizer, list(scale["bits"])
    A, B = ex.system.A, ex.system.B
    seeds = np.random.SeedSequence(1).spawn(realizations)

    def engine(name):
        t0 = time.perf_counter()
        for ss in seeds:
            for mo in quantized_moments(prep, bits, spec, np.random.default_rng(ss), engine=name):
                idn = identify(mo, "ls")
                relative_errors(idn.A, idn.B, A, B)
        return time.perf_counter() - t0

    per = len(bits) * realizations
    engine("auto")  # warm up (compile or cache load)
    res = {"engine (numba)": [], "fused kernel floor": [], "numpy reference": []}
    for _ in range(repeats):
        res["engine (numba)"].append(engine("auto") / per)
        res["fused kernel floor"].append(_kernel_floor(prep, bits, spec, seeds) / per)
        res["numpy reference"].append(engine("numpy") / per)
    out = {k: _stats(v) for k, v in res.items()}
    out["ratio_engine_to_floor"] = out["engine (numba)"]["best"] / out["fused kernel floor"]["best"]
    out["ratio_numpy_to_engine"] = out["numpy reference"]["best"] / out["engine (numba)"]["best"]
    return out


_PROBE = (
    "import time; t0 = time.perf_counter(); import numba; t1 = time.perf_counter(); "
    "import numpy as np; from qsid_core import QuantizerSpec, dc_motor, prepare, quantized_moments, simulate; from qsid_core.quantization import kernels; "
    "d = simulate(dc_motor(), 2, 50, seed=0); s = QuantizerSpec(); "
    "p = prepare(d, s); t2 = time.perf_counter(); quantized_moments(p, [4], s, np.random.default_rng(0)); "
    "kernels.box_qp_pdas(np.eye(2)[None], np.ones((1, 2)), np.ones(2), np.zeros((1, 2), bool), "
    "np.zeros((1, 2), bool)); t3 = time.perf_counter(); print(t1 - t0, t3 - t2)"
)


def numba_costs() -> dict:
    """Section 3: import, compile (empty cache) and cached load, each in a fresh process."""
    with tempfile.TemporaryDirectory() as d:
        env = {**os.environ, "NUMBA_CACHE_DIR": d}
        runs = []
        for _ in range(2):  # first: compile into the empty cache; second: load from it
            out = subprocess.run(
                [sys.executable, "-c", _PROBE],
                cwd=ROOT,
                env=env,
                capture_output=True,
                text=True,
                timeout=300,
                check=True,
            )
            runs.append([float(v) for v in out.stdout.split()])
    return dict(import_numba_s=runs[1][0], first_call_compile_s=runs[0][1], first_call_cached_s=runs[1][1])


def sweep_wall(repeats: int, quick: bool) -> dict:
    """Section 4: ``python -m app.cli sweep --json -q`` wall time (paper scale unless quick)."""
    cmd = [sys.executable, "-m", "app.cli", "sweep", "--json", "-q"]
    if quick:
        cmd += ["--trajectories", "20", "--steps", "100", "--realizations", "5"]
    out = {}
    for label, extra in (("numba kernels", {}), ("QSID_NO_NUMBA=1", {"QSID_NO_NUMBA": "1"})):
        ts = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            subprocess.run(cmd, cwd=ROOT, env={**os.environ, **extra}, capture_output=True, check=True, timeout=600)
            ts.append(time.perf_counter() - t0)
        out[label] = _stats(ts)
    return out


def _row(label, st, unit=1e3, fmt="{:9.3f}"):
    return f"  {label:<34}{fmt.format(st['best'] * unit)}{fmt.format(st['median'] * unit)}"


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small scale, one repeat (smoke test)")
    ap.add_argument("--repeats", type=int, default=None, help="repeats of the fast variants (default 3; quick 1)")
    ap.add_argument("--osqp-repeats", type=int, default=None, help="repeats of the old OSQP stage (default 2)")
    ap.add_argument("--ident-realizations", type=int, default=None, help="realizations timed (default 10)")
    ap.add_argument("--skip", default="", help="comma-separated sections to skip: mpc, ident, numba, sweep")
    args = ap.parse_args(argv)
    scale = QUICK if args.quick else PAPER
    rp = args.repeats or (1 if args.quick else 3)
    orp = args.osqp_repeats or (1 if args.quick else 2)
    skip = {s.strip() for s in args.skip.split(",") if s.strip()}
    out: dict = dict(
        benchmark="bench_speed",
        quick=bool(args.quick),
        cores=os.cpu_count(),
        numba=kernels.AVAILABLE,
        numba_reason=kernels.REASON,
    )
    print(
        f"QSID speed targets ({'quick' if args.quick else 'paper scale'}); {os.cpu_count()} shared cores; "
        f"compiled kernels: {'yes' if kernels.AVAILABLE else 'no (' + kernels.REASON + ')'}"
    )
    if "mpc" not in skip:
        r = out["saturated_mpc"] = saturated_mpc(scale, rp, orp)
        print(
            f"\n1. saturated Boeing MPC stage: {r['loops']} loops x {SATURATED['steps']} steps, |u| <= 0.3, "
            f"x0 = 20*[1,1,0,0]; {r['qp_steps']} constrained steps"
        )
        print(f"  {'':<34}{'best [s]':>9}{'median':>9}")
        print(_row("previous engine (OSQP, sparse)", r["old"], 1, "{:9.3f}"))
        print(_row("new engine (active set / DAQP)", r["new"], 1, "{:9.3f}"))
        print(
            f"  speed-up {r['speedup']:.1f}x (target >= 25x: {'MET' if r['speedup'] >= 25 else 'NOT met'}); "
            f"max |du| {r['max_abs_du']:.1e}, max rel. d cost {r['max_rel_dcost']:.1e}, "
            f"failure mismatches {r['failure_mismatches']}"
        )
    if "ident" not in skip and kernels.AVAILABLE:
        nr = args.ident_realizations or (2 if args.quick else 10)
        r = out["identification"] = identification(scale, rp, nr)
        print(
            f"\n2. identification per (b, realization), dc-motor {scale['trajectories']} x {scale['steps']}, "
            f"{nr} realizations x {len(scale['bits'])} word lengths"
        )
        print(f"  {'':<34}{'best [ms]':>9}{'median':>9}")
        for k in ("engine (numba)", "fused kernel floor", "numpy reference"):
            print(_row(k, r[k]))
        print(
            f"  engine / floor {r['ratio_engine_to_floor']:.2f}x (target <= 1.5x: "
            f"{'MET' if r['ratio_engine_to_floor'] <= 1.5 else 'NOT met'}); numpy / engine "
            f"{r['ratio_numpy_to_engine']:.2f}x"
        )
    if "numba" not in skip and kernels.AVAILABLE:
        r = out["numba_costs"] = numba_costs()
        print(
            f"\n3. numba (fresh processes): import {r['import_numba_s']:.2f} s, first call with an empty cache "
            f"(compile) {r['first_call_compile_s']:.2f} s, first call with the cache filled "
            f"{r['first_call_cached_s']:.2f} s"
        )
    if "sweep" not in skip:
        r = out["sweep_wall"] = sweep_wall(rp, args.quick)
        print(f"\n4. `qsid sweep` ({'small' if args.quick else 'paper scale'}, dc-motor, MPC on), one process, wall")
        print(f"  {'':<34}{'best [s]':>9}{'median':>9}")
        for k, st in r.items():
            print(_row(k, st, 1))
        best = r["numba kernels"]["best"]
        print(f"  target <= 2.5 s: {'MET' if best <= 2.5 else 'NOT met'} ({best:.2f} s)")
    print("RESULT " + json.dumps(out))
    return out


if __name__ == "__main__":
    main()
