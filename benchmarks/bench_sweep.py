#!/usr/bin/env python
"""Paper-scale sweep: ``qsid_core.run_sweep`` against a naive per-realization numpy loop.

The science (letter, Section V): the DC motor, 200 trajectories x 1000 steps of
random-input data, word lengths b = 1..16, 50 subtractive-dither realizations per
b, least squares, and for every identified model an MPC closed loop of 50 steps
(horizon 10, |u| <= 1, Qf = DARE) on the true system.

* **fast**: :func:`qsid_core.run_sweep`, timed in-process, with a
  ``ThreadPoolExecutor(2)``, with a ``ProcessPoolExecutor(2)``, and with a
  ``ProcessPoolExecutor(2)`` whose workers limit OpenBLAS to one thread
  (threadpoolctl; the engine's thousands of tiny BLAS/LAPACK calls gain
  nothing from BLAS threads and two workers x two BLAS threads oversubscribe two
  cores). Always the full sweep; best and median of ``--repeats`` runs; each
  pool's first, cold run -- which pays for starting the workers -- is reported too.
* **naive**: the same numbers computed the straightforward way -- for each b, for
  each realization: draw the unit dither for the whole data set, quantize states
  and inputs with the reference :func:`qsid_core.quantization.quantize.quantize`, build X, X+,
  U and Psi explicitly, ``G = X+ Psi^T (Psi Psi^T)^-1`` (letter, eq. (7)), then the
  MPC closed loop with OSQP at every step, set up once per model (the stronger
  baseline) and, separately, once per step. It is timed on
  ``--naive-realizations K`` realizations (best of ``--naive-repeats``) and
  extrapolated linearly to the full count (printed as such).

* **cli**: ``qsid sweep --json -q`` (``python -m app.cli``) at the same settings, each run a new process timed
  from its start to its end, as a user runs it: the study path (:class:`qsid_core.Study` over the CLI's
  executor, two threads by default), start-up (imports, numba's cached kernels) included. Per run: the wall
  clock, the CPU seconds of the process (user + system, from ``getrusage``), the 1-minute load average at its
  start and the engine's own ``timing_s.total``. The first run is a warm-up (it fills Python's bytecode
  cache and numba's kernel cache, as an installation's first run does) and is not counted; the CLI runs
  with Python's bytecode cache on (``PYTHONDONTWRITEBYTECODE`` removed from its environment). Its JSON
  must equal the in-process engine's result at the same settings (printed).

Correctness: the naive loop draws realization r's dither from the same
``SeedSequence(dither_seed).spawn(R)[r]`` stream as the engine, so the identified
``[A^, B^]`` must agree to rounding; the script prints the max difference, the
max relative difference of the closed-loop costs and the failure agreement.

The targets: the CLI at paper scale within 3 s of wall clock and at least 20x faster than the
naive loop (OSQP set up per model) measured in the same run. On a machine other jobs share, wall clocks
include waiting for a CPU: the CPU seconds and the load average beside them say how much.

Run ``python benchmarks/bench_sweep.py`` (paper scale) or ``--quick``; ``--save FILE`` also writes the
output to FILE with a header (command, time, CPUs, load average, code). The last line is
``RESULT {json}`` with every measured number.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from threadpoolctl import threadpool_info, threadpool_limits

from qsid_core import (
    MPCConfig,
    MPCWeights,
    SweepConfig,
    get_system,
    quantize,
    run_sweep,
    simulate,
)


def blas_threads() -> dict:
    """Threads of each BLAS library loaded in this process (file name -> threads), by threadpoolctl."""
    return {
        i["filepath"].rsplit("/", 1)[-1]: int(i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas"
    }


def set_blas_threads(n: int = 1) -> None:
    """Limit every loaded BLAS to ``n`` threads for the rest of this process (also a pool initializer)."""
    threadpool_limits(limits=int(n), user_api="blas")


PAPER = dict(
    system="dc-motor",
    bits=tuple(range(1, 17)),
    realizations=50,
    trajectories=200,
    steps=1000,
    horizon=10,
    mpc_steps=50,
    u_max=1.0,
)
QUICK = dict(
    system="dc-motor", bits=(1, 3, 6, 10), realizations=4, trajectories=8, steps=150, horizon=5, mpc_steps=10, u_max=1.0
)


def make_config(scale: dict, system: str | None = None) -> SweepConfig:
    """The sweep's :class:`SweepConfig` (LS, default quantizer: subtractive dither, per-channel range)."""
    return SweepConfig(
        system=system or scale["system"],
        bits=scale["bits"],
        realizations=scale["realizations"],
        trajectories=scale["trajectories"],
        steps=scale["steps"],
        estimator="ls",
        mpc=MPCConfig(horizon=scale["horizon"], steps=scale["mpc_steps"], u_max=scale["u_max"]),
    )


# ----------------------------------------------------------------------------------------------
# fast: the engine
# ----------------------------------------------------------------------------------------------
def fast_numbers(res) -> dict:
    """Per-b arrays of a :class:`SweepResult` (what the naive loop reproduces)."""
    out = {}
    for b in res.bits:
        idn, lp = res.identification[b], res.loops.get(b)
        out[b] = dict(
            A=idn.A_hat,
            B=idn.B_hat,
            err_A=idn.err_A,
            err_B=idn.err_B,
            cost=None if lp is None else lp.cost,
            failed=None if lp is None else lp.failed,
            qp_steps=None if lp is None else lp.qp_steps,
        )
    return out


EXECUTORS = ("inline", "thread", "process", "process-1blas")
LABELS = {
    "inline": "run_sweep in-process",
    "thread": "run_sweep + ThreadPoolExecutor(2)",
    "process": "run_sweep + ProcessPoolExecutor(2)",
    "process-1blas": "  same, workers with 1 BLAS thread",
}


def make_executor(kind: str):
    """None (in-process), ThreadPoolExecutor(2), ProcessPoolExecutor(2), or the latter with 1-thread OpenBLAS."""
    if kind == "inline":
        return None
    if kind == "thread":
        return ThreadPoolExecutor(2)
    if kind == "process":
        return ProcessPoolExecutor(2)
    if kind == "process-1blas":
        return ProcessPoolExecutor(2, initializer=set_blas_threads, initargs=(1,))
    raise ValueError(f"unknown executor {kind!r}; choose from {EXECUTORS}")


def time_fast(cfg: SweepConfig, kind: str, repeats: int) -> dict:
    """Time ``run_sweep(cfg)`` ``repeats`` times with executor ``kind`` (see :data:`EXECUTORS`).

    A pool is created once and reused, so the first run (``cold``) also pays for starting the workers.
    """
    pool = make_executor(kind)
    times, stages, res = [], [], None
    try:
        for _ in range(repeats):
            t0 = time.perf_counter()
            res = run_sweep(cfg, executor=pool)
            times.append(time.perf_counter() - t0)
            stages.append(res.timing_s)
    finally:
        if pool is not None:
            pool.shutdown()
    ib = int(np.argmin(times))
    return dict(
        kind=kind,
        times=times,
        best=min(times),
        median=statistics.median(times),
        cold=times[0],
        stages_best=stages[ib],
        result=res,
    )


# ----------------------------------------------------------------------------------------------
# cli: `qsid sweep` as a user runs it, one process per run
# ----------------------------------------------------------------------------------------------
def cli_args(scale: dict, system: str | None = None) -> list[str]:
    """``qsid sweep`` options for ``scale`` (the paper scale is the CLI's defaults, spelled out)."""
    b = scale["bits"]
    bits = f"{b[0]}:{b[-1]}" if list(b) == list(range(b[0], b[-1] + 1)) else ",".join(map(str, b))
    return [
        "--system",
        system or scale["system"],
        "--bits",
        bits,
        "--realizations",
        str(scale["realizations"]),
        "--trajectories",
        str(scale["trajectories"]),
        "--steps",
        str(scale["steps"]),
        "--horizon",
        str(scale["horizon"]),
        "--mpc-steps",
        str(scale["mpc_steps"]),
        "--u-max",
        str(scale["u_max"]),
    ]


def _cli_env() -> dict:
    """The CLI's environment: this one with Python's bytecode cache on, this checkout first on the path."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    return env


def run_cli(args: list[str]) -> dict:
    """One ``qsid sweep --json -q ARGS`` process: wall and CPU seconds, load average at its start, its JSON."""
    cmd = [sys.executable, "-m", "app.cli", "sweep", "--json", "-q", *args]
    load = os.getloadavg()[0]
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run(cmd, cwd=ROOT, env=_cli_env(), capture_output=True, text=True, timeout=900)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if out.returncode != 0:
        raise RuntimeError(f"qsid sweep failed ({out.returncode}): {out.stderr.strip()[-500:]}")
    data = json.loads(out.stdout)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    return dict(wall=wall, cpu=cpu, load=load, engine=float(data["timing_s"]["total"]), json=data)


def time_cli(args: list[str], repeats: int) -> dict:
    """``repeats`` counted CLI runs after one warm-up run (bytecode and numba caches filled, not counted)."""
    run_cli(args)
    runs = [run_cli(args) for _ in range(repeats)]
    walls = [r["wall"] for r in runs]
    return dict(
        runs=[{k: v for k, v in r.items() if k != "json"} for r in runs],
        best=min(walls),
        median=statistics.median(walls),
        cpu_median=statistics.median(r["cpu"] for r in runs),
        engine_median=statistics.median(r["engine"] for r in runs),
        json=runs[-1]["json"],
    )


def same_json(a: dict, b: dict) -> bool:
    """Two sweep JSONs equal in every number and string but the timings."""
    return {k: v for k, v in a.items() if k != "timing_s"} == {k: v for k, v in b.items() if k != "timing_s"}


# ----------------------------------------------------------------------------------------------
# naive: one realization at a time, explicit matrices, OSQP at every MPC step
# ----------------------------------------------------------------------------------------------
def naive_qp(A_hat, B_hat, Q, R, Qf, N, u_max):
    """Sparse MPC QP in z = [x_0..x_N, u_0..u_{N-1}] (cost z'Pz), as in OSQP's MPC example."""
    n, m = B_hat.shape
    P = sp.block_diag([sp.kron(sp.eye(N), Q), Qf, sp.kron(sp.eye(N), R)], format="csc")
    q = np.zeros((N + 1) * n + N * m)
    Ax = sp.kron(sp.eye(N + 1), -sp.eye(n)) + sp.kron(sp.eye(N + 1, k=-1), A_hat)
    Bu = sp.kron(sp.vstack([sp.csc_matrix((1, N)), sp.eye(N)]), B_hat)
    Aeq = sp.hstack([Ax, Bu])
    Aineq = sp.hstack([sp.csc_matrix((N * m, (N + 1) * n)), sp.eye(N * m)])
    Acon = sp.vstack([Aeq, Aineq], format="csc")
    lo = np.concatenate([np.zeros((N + 1) * n), np.tile(-u_max, N)])
    hi = np.concatenate([np.zeros((N + 1) * n), np.tile(u_max, N)])
    return sp.triu(P, format="csc"), q, Acon, lo, hi


def naive_closed_loop(A_hat, B_hat, A, B, w: MPCWeights, mcfg: MPCConfig, osqp_setup: str = "model"):
    """MPC on (A_hat, B_hat) in closed loop on (A, B); OSQP at every step. Returns (cost, inputs, failure)."""
    import osqp

    if np.any(w.x_ref != 0) or w.x_max is not None or w.xf_max is not None:
        raise ValueError("the naive loop implements x_ref = 0 and input bounds only")
    Q, R, N, u_max = w.Q, w.R, mcfg.horizon, w.u_max
    n, m = B_hat.shape
    nan_inputs = np.full((mcfg.steps, m), np.nan)
    if not (np.all(np.isfinite(A_hat)) and np.all(np.isfinite(B_hat))):
        return np.nan, nan_inputs, "dare"
    try:
        Qf = sla.solve_discrete_are(A_hat, B_hat, Q, R)
    except (np.linalg.LinAlgError, ValueError):
        return np.nan, nan_inputs, "dare"
    Qf = (Qf + Qf.T) / 2
    K = np.linalg.solve(R + B_hat.T @ Qf @ B_hat, B_hat.T @ Qf @ A_hat)
    if (
        not np.all(np.isfinite(Qf))
        or np.abs(np.linalg.eigvals(A_hat - B_hat @ K)).max() >= 1.0
        or np.linalg.eigvalsh(Qf).min() < -1e-9
    ):
        return np.nan, nan_inputs, "dare"
    P, q, Acon, lo, hi = naive_qp(A_hat, B_hat, Q, R, Qf, N, u_max)
    settings = dict(
        verbose=False, polishing=True, warm_starting=True, eps_abs=mcfg.eps, eps_rel=mcfg.eps, max_iter=mcfg.max_iter
    )
    solver = None
    x = np.array(w.x0, dtype=float)
    cost = 0.0
    us = np.empty((mcfg.steps, m))
    i0 = (N + 1) * n
    S = osqp.SolverStatus
    for t in range(mcfg.steps):
        lo[:n] = -x
        hi[:n] = -x
        if solver is None or osqp_setup == "step":
            solver = osqp.OSQP()
            solver.setup(P, q, Acon, lo, hi, **settings)
        else:
            solver.update(l=lo, u=hi)
        res = solver.solve(raise_error=False)
        st = res.info.status_val
        if st not in (S.OSQP_SOLVED, S.OSQP_SOLVED_INACCURATE):
            kind = (
                "infeasible"
                if st in (S.OSQP_PRIMAL_INFEASIBLE, S.OSQP_PRIMAL_INFEASIBLE_INACCURATE)
                else "max_iter"
                if st == S.OSQP_MAX_ITER_REACHED
                else "solver"
            )
            return np.nan, nan_inputs, kind
        u = np.clip(res.x[i0 : i0 + m], -u_max, u_max)
        cost += float(x @ Q @ x + u @ R @ u)
        us[t] = u
        x = A @ x + B @ u
        if not np.all(np.isfinite(x)) or np.abs(x).max() > 1e12:
            return np.nan, nan_inputs, "diverged"
    return cost, us, ""


def naive_sweep(cfg: SweepConfig, realizations, osqp_setup: str = "model") -> dict:
    """The sweep done naively for the given realization indices (all b). Times fixed and per-realization work."""
    t0, c0 = time.perf_counter(), time.process_time()
    system = get_system(cfg.system)
    A, B, n, m = system.A, system.B, system.n, system.m
    J, S, p = cfg.trajectories, cfg.steps, system.n + system.m
    data = simulate(system, J, S, cfg.data_seed)
    states, inputs = data.states, data.inputs  # (J, S+1, n), (J, S, m)
    lo = np.concatenate([states.reshape(-1, n).min(axis=0), inputs.reshape(-1, m).min(axis=0)])
    hi = np.concatenate([states.reshape(-1, n).max(axis=0), inputs.reshape(-1, m).max(axis=0)])
    seeds = np.random.SeedSequence(cfg.dither_seed).spawn(cfg.realizations)
    w = cfg.mpc.resolve(system)
    true_cost = naive_closed_loop(A, B, A, B, w, cfg.mpc, osqp_setup)[0]
    t_fixed = time.perf_counter() - t0
    realizations = list(realizations)
    K = len(realizations)
    out = {}
    t_ident = t_mpc = 0.0
    t1 = time.perf_counter()
    for b in cfg.bits:
        Ah = np.empty((K, n, n))
        Bh = np.empty((K, n, m))
        eA, eB, cost = np.empty(K), np.empty(K), np.empty(K)
        fails = []
        for i, r in enumerate(realizations):
            # realization r's unit dither: one U[-1/2, 1/2] draw per (sample, channel), padding included
            ta = time.perf_counter()
            rng = np.random.default_rng(seeds[r])
            unit = rng.uniform(-0.5, 0.5, size=(J, S + 1, p))
            xq = quantize(states, lo[:n], hi[:n], b, unit_dither=unit[:, :, :n]).values
            uq = quantize(inputs, lo[n:], hi[n:], b, unit_dither=unit[:, :S, n:]).values
            X = xq[:, :-1, :].reshape(-1, n).T  # (n, T)
            Xp = xq[:, 1:, :].reshape(-1, n).T  # (n, T)
            U = uq.reshape(-1, m).T  # (m, T)
            Psi = np.vstack([X, U])  # (n+m, T)
            G = np.linalg.solve(Psi @ Psi.T, Psi @ Xp.T).T  # X+ Psi^T (Psi Psi^T)^-1
            Ah[i], Bh[i] = G[:, :n], G[:, n:]
            eA[i] = np.linalg.norm(A - Ah[i]) / np.linalg.norm(A)
            eB[i] = np.linalg.norm(B - Bh[i]) / np.linalg.norm(B)
            tb = time.perf_counter()
            cost[i], _, f = naive_closed_loop(Ah[i], Bh[i], A, B, w, cfg.mpc, osqp_setup)
            fails.append(f)
            tc = time.perf_counter()
            t_ident += tb - ta
            t_mpc += tc - tb
        out[b] = dict(A=Ah, B=Bh, err_A=eA, err_B=eB, cost=cost, failed=np.array([bool(f) for f in fails]))
    t_loop = time.perf_counter() - t1
    cpu = time.process_time() - c0  # this process's CPU seconds (one Python thread; BLAS may add threads)
    return dict(
        per_b=out,
        realizations=realizations,
        t_fixed=t_fixed,
        t_loop=t_loop,
        t_ident=t_ident,
        t_mpc=t_mpc,
        true_cost=true_cost,
        osqp_setup=osqp_setup,
        cpu=cpu,
    )


def extrapolate_cpu(naive: dict, total_realizations: int) -> float:
    """:func:`extrapolate` of the CPU seconds (fixed part taken at the wall clock's share)."""
    K = len(naive["realizations"])
    total = naive["t_fixed"] + naive["t_loop"]
    share = naive["t_fixed"] / total if total > 0 else 0.0
    return naive["cpu"] * (share + (1 - share) * total_realizations / K)


def extrapolate(naive: dict, total_realizations: int) -> float:
    """Fixed cost plus the per-realization loop scaled linearly to ``total_realizations``."""
    K = len(naive["realizations"])
    return naive["t_fixed"] + naive["t_loop"] * total_realizations / K


# ----------------------------------------------------------------------------------------------
# correctness
# ----------------------------------------------------------------------------------------------
def compare(fast: dict, naive: dict) -> dict:
    """Max differences between the engine's and the naive loop's numbers on the naive's realizations."""
    idx = naive["realizations"]
    dG, dcost, dmean_err, fail_mismatch, compared = 0.0, 0.0, 0.0, 0, 0
    for b, nv in naive["per_b"].items():
        fv = fast[b]
        dG = max(dG, float(np.abs(fv["A"][idx] - nv["A"]).max()), float(np.abs(fv["B"][idx] - nv["B"]).max()))
        dmean_err = max(
            dmean_err,
            abs(float(fv["err_A"][idx].mean() - nv["err_A"].mean())),
            abs(float(fv["err_B"][idx].mean() - nv["err_B"].mean())),
        )
        if fv["cost"] is not None:
            fc, nc = fv["cost"][idx], nv["cost"]
            fail_mismatch += int(np.sum(fv["failed"][idx] != nv["failed"]))
            ok = np.isfinite(fc) & np.isfinite(nc)
            compared += int(ok.sum())
            if ok.any():
                dcost = max(dcost, float(np.max(np.abs(fc[ok] - nc[ok]) / np.maximum(np.abs(fc[ok]), 1e-300))))
    return dict(
        max_abs_diff_AB=dG,
        max_rel_diff_cost=dcost,
        max_diff_mean_err=dmean_err,
        failure_mismatches=fail_mismatch,
        loops_compared=compared,
    )


def correctness_check(scale: dict | None = None, realizations=None, osqp_setup: str = "model") -> dict:
    """Run the engine and the naive loop on ``scale`` (default: quick) and return :func:`compare`'s diffs."""
    cfg = make_config(scale or QUICK)
    res = run_sweep(cfg)
    naive = naive_sweep(cfg, range(cfg.realizations) if realizations is None else realizations, osqp_setup)
    return compare(fast_numbers(res), naive)


def executor_agreement(results: dict) -> float:
    """Max |A^, B^ difference| between the sweeps run with different executors (should be exactly 0)."""
    kinds = list(results)
    ref = fast_numbers(results[kinds[0]])
    d = 0.0
    for k in kinds[1:]:
        other = fast_numbers(results[k])
        for b in ref:
            d = max(
                d, float(np.abs(ref[b]["A"] - other[b]["A"]).max()), float(np.abs(ref[b]["B"] - other[b]["B"]).max())
            )
    return d


# ----------------------------------------------------------------------------------------------
def _fmt(x, spec=".3e"):
    return "-" if x is None or (isinstance(x, float) and not np.isfinite(x)) else format(x, spec)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small problem (seconds; used by the smoke test)")
    ap.add_argument("--system", default=None, help="system preset (default dc-motor)")
    ap.add_argument(
        "--naive-realizations",
        type=int,
        default=None,
        help="realizations the naive loop is timed on before linear extrapolation (default 5; quick: all)",
    )
    ap.add_argument(
        "--naive-osqp",
        choices=("model", "step", "both"),
        default="both",
        help="naive MPC: OSQP set up once per model (the stronger baseline), once per step, or both "
        "(default; the ratio target is judged against the per-model one)",
    )
    ap.add_argument("--naive-repeats", type=int, default=None, help="runs of each naive variant (default 2; quick 1)")
    ap.add_argument("--repeats", type=int, default=None, help="runs of each fast variant (default 5; quick: 1)")
    ap.add_argument(
        "--executors",
        default=",".join(EXECUTORS),
        help="comma-separated subset of " + ",".join(EXECUTORS) + " (default: all)",
    )
    ap.add_argument(
        "--cli-repeats",
        type=int,
        default=None,
        help="counted runs of `qsid sweep` (after one warm-up run; default 3; quick: 1; 0: skip)",
    )
    args = ap.parse_args(argv)

    scale = QUICK if args.quick else PAPER
    cfg = make_config(scale, args.system)
    R = cfg.realizations
    K = args.naive_realizations if args.naive_realizations is not None else (R if args.quick else 5)
    K = max(1, min(K, R))
    repeats = args.repeats if args.repeats is not None else (1 if args.quick else 5)
    nrep = args.naive_repeats if args.naive_repeats is not None else (1 if args.quick else 2)
    modes = ("model", "step") if args.naive_osqp == "both" else (args.naive_osqp,)
    kinds = [k.strip() for k in args.executors.split(",") if k.strip()]
    for k in kinds:
        if k not in EXECUTORS:
            ap.error(f"unknown executor {k!r}")

    bits = cfg.bits
    print(
        f"QSID sweep benchmark ({'quick' if args.quick else 'paper scale'}): {get_system(cfg.system).name}, "
        f"{cfg.trajectories} trajectories x {cfg.steps} steps, b = {bits[0]}..{bits[-1]} ({len(bits)} values), "
        f"{R} realizations, LS, MPC {cfg.mpc.steps} steps, horizon {cfg.mpc.horizon}, |u| <= {scale['u_max']:g}"
    )
    print(
        f"machine: {os.cpu_count()} cores (shared: timings are noisy; ratios are measured in the same run); "
        f"OpenBLAS threads in this process: {blas_threads() or 'unknown'}"
    )

    # warm-up (imports, OSQP/scipy first calls): a tiny sweep and a tiny naive loop, not timed
    warm = make_config(QUICK, args.system)
    run_sweep(warm)
    naive_sweep(warm, [0], "model")

    fast = {}
    for k in kinds:
        fast[k] = time_fast(cfg, k, repeats)
    cli_repeats = args.cli_repeats if args.cli_repeats is not None else (1 if args.quick else 3)
    cli = time_cli(cli_args(scale, args.system), cli_repeats) if cli_repeats > 0 else None
    naive, naive_times = {}, {}
    for mode in modes:
        runs = [naive_sweep(cfg, range(K), mode) for _ in range(nrep)]
        naive_times[mode] = [extrapolate(r, R) for r in runs]
        naive[mode] = runs[int(np.argmin(naive_times[mode]))]
    t_naive = {mode: min(v) for mode, v in naive_times.items()}
    cpu_naive = {mode: extrapolate_cpu(nv, R) for mode, nv in naive.items()}
    main_mode = modes[0]

    ref_kind = kinds[0]
    fnum = fast_numbers(fast[ref_kind]["result"])
    diffs = compare(fnum, naive[main_mode])
    diffs_modes = {mode: compare(fnum, nv) for mode, nv in naive.items()}
    exec_diff = executor_agreement({k: v["result"] for k, v in fast.items()}) if len(kinds) > 1 else 0.0

    # ----- timing table
    label = LABELS
    print()
    print(f"{'variant':<46}{'best [s]':>10}{'median [s]':>12}{'runs':>6}   stages of best run [s]")
    for k in kinds:
        f = fast[k]
        st = f["stages_best"]
        print(
            f"{label[k]:<46}{f['best']:>10.3f}{f['median']:>12.3f}{len(f['times']):>6}   "
            f"data {st['data']:.2f}  identify {st['identify']:.2f}  theory {st['theory']:.2f}  mpc {st['mpc']:.2f}"
        )
    for k in ("process", "process-1blas"):
        if k in fast:
            print(f"{'  (' + k + ' cold first run, incl. start)':<46}{fast[k]['cold']:>10.3f}")
    if cli is not None:
        print(
            f"{'qsid sweep (CLI, a new process per run)':<46}{cli['best']:>10.3f}{cli['median']:>12.3f}"
            f"{len(cli['runs']):>6}   CPU {cli['cpu_median']:.2f} s, engine {cli['engine_median']:.2f} s (medians)"
        )
        print(f"{'':<46}   a new process per run after a warm-up run, Python's bytecode cache on")
        for i, r in enumerate(cli["runs"]):
            print(
                f"{'':<46}   run {i + 1}: wall {r['wall']:.2f} s, CPU {r['cpu']:.2f} s, engine {r['engine']:.2f} s, "
                f"load average {r['load']:.1f}"
            )
    extra = "measured in full" if K == R else f"EXTRAPOLATED linearly from {K} measured realizations to {R}"
    for mode in modes:
        nv = naive[mode]
        print(
            f"{'naive loop, OSQP set up per ' + mode:<46}{t_naive[mode]:>10.3f}"
            f"{statistics.median(naive_times[mode]):>12.3f}{nrep:>6}   {extra}"
        )
        print(
            f"{'':<46}   best run: fixed {nv['t_fixed']:.3f} s + {nv['t_loop']:.3f} s for {K} realization(s) x "
            f"{len(bits)} b = {nv['t_loop'] / (K * len(bits)) * 1e3:.1f} ms per (b, realization):"
        )
        print(f"{'':<46}   quantize + LS {nv['t_ident']:.3f} s, MPC closed loops {nv['t_mpc']:.3f} s")
        print(f"{'':<46}   CPU {cpu_naive[mode]:.3f} s (extrapolated alike; one Python thread, BLAS its own)")
    print()
    best_fast = min(f["best"] for f in fast.values())
    ratios = {mode: {k: t_naive[mode] / fast[k]["best"] for k in kinds} for mode in modes}
    for mode in modes:
        for k in kinds:
            print(f"speed-up naive (OSQP per {mode:<5}) / {label[k].strip():<36}: {ratios[mode][k]:8.1f}x")
    print(f"fastest engine variant: {best_fast:.3f} s  (target <= 3 s: {'MET' if best_fast <= 3.0 else 'NOT met'})")
    for mode in modes:
        r = t_naive[mode] / best_fast
        print(f"naive (OSQP per {mode}) / fastest engine variant: {r:.1f}x")
    cli_same = None
    if cli is not None:
        from app.cli.output import sweep_dict

        cli_same = same_json(cli["json"], json.loads(json.dumps(sweep_dict(fast[ref_kind]["result"]))))
        load = statistics.median(r["load"] for r in cli["runs"])
        print(
            f"qsid sweep, median wall: {cli['median']:.3f} s  (target <= 3 s: "
            f"{'MET' if cli['median'] <= 3.0 else 'NOT met'}; CPU {cli['cpu_median']:.2f} s on "
            f"{os.cpu_count()} cores, load average {load:.1f} at the runs' starts)"
        )
        for mode in modes:
            r = t_naive[mode] / cli["median"]
            print(
                f"naive (OSQP per {mode}) / qsid sweep (median walls): {r:.1f}x  (target >= 20x: "
                f"{'MET' if r >= 20 else 'NOT met'}); CPU seconds: {cpu_naive[mode] / cli['cpu_median']:.1f}x"
            )
        print(f"qsid sweep's JSON equals the in-process engine's result: {'yes' if cli_same else 'NO'}")

    # ----- science table
    res = fast[ref_kind]["result"]
    print()
    print(f"per-b results (engine: all {R} realizations; naive vs engine: the {K} realization(s) the naive loop ran)")
    print(
        f"{'b':>3}{'errA eng':>11}{'errB eng':>11}{'cost eng':>11}{'fail':>5}{'osqp':>6}"
        f"{'errA naive':>12}{'errA eng@K':>12}{'cost naive':>12}{'cost eng@K':>12}"
    )
    rows = []
    for b in bits:
        fv, nv = fnum[b], naive[main_mode]["per_b"][b]
        fc = fv["cost"]
        row = dict(
            bits=b,
            err_A=float(fv["err_A"].mean()),
            err_B=float(fv["err_B"].mean()),
            cost=float(np.nanmean(fc)) if np.isfinite(fc).any() else None,
            failed=int(fv["failed"].sum()),
            qp_steps=int(fv["qp_steps"]),
            naive_err_A=float(nv["err_A"].mean()),
            engine_err_A_at_K=float(fv["err_A"][:K].mean()),
            naive_cost=float(np.nanmean(nv["cost"])) if np.isfinite(nv["cost"]).any() else None,
            engine_cost_at_K=float(np.nanmean(fc[:K])) if np.isfinite(fc[:K]).any() else None,
            naive_failed=int(nv["failed"].sum()),
        )
        rows.append(row)
        print(
            f"{b:>3}{row['err_A']:>11.3e}{row['err_B']:>11.3e}{_fmt(row['cost'], '>11.4f')}{row['failed']:>5}"
            f"{row['qp_steps']:>6}{row['naive_err_A']:>12.3e}{row['engine_err_A_at_K']:>12.3e}"
            f"{_fmt(row['naive_cost'], '>12.4f')}{_fmt(row['engine_cost_at_K'], '>12.4f')}"
        )
    tc = res.true_loop.cost[0] if res.true_loop is not None else float("nan")
    print(f"true-model MPC cost: engine {tc:.10f}, naive {naive[main_mode]['true_cost']:.10f}")
    print(
        f"slopes of log10(mean error) vs b: A {res.slope_A:.4f}, B {res.slope_B:.4f}  (letter: about -0.30 = log10(1/2))"
    )

    print()
    print(f"correctness (engine vs naive, same dither streams, realizations 0..{K - 1}):")
    print(f"  max |[A^,B^]_engine - [A^,B^]_naive|      = {diffs['max_abs_diff_AB']:.3e}")
    print(
        f"  max relative diff of closed-loop cost     = {diffs['max_rel_diff_cost']:.3e}  "
        f"({diffs['loops_compared']} loops compared)"
    )
    print(f"  max diff of mean relative errors          = {diffs['max_diff_mean_err']:.3e}")
    print(f"  MPC failure mismatches                    = {diffs['failure_mismatches']}")
    if len(modes) > 1:
        o = diffs_modes[modes[1]]
        print(
            f"  (naive with OSQP per {modes[1]}: max |d[A^,B^]| {o['max_abs_diff_AB']:.3e}, "
            f"max rel. d cost {o['max_rel_diff_cost']:.3e}, failure mismatches {o['failure_mismatches']})"
        )
    if len(kinds) > 1:
        print(f"  max |[A^,B^]| difference between executors = {exec_diff:.3e}")

    result = dict(
        benchmark="bench_sweep",
        quick=bool(args.quick),
        system=get_system(cfg.system).name,
        config=dict(
            trajectories=cfg.trajectories,
            steps=cfg.steps,
            bits=list(bits),
            realizations=R,
            horizon=cfg.mpc.horizon,
            mpc_steps=cfg.mpc.steps,
            u_max=scale["u_max"],
            estimator="ls",
        ),
        cores=os.cpu_count(),
        blas_threads=blas_threads(),
        fast={
            k: dict(
                best_s=f["best"],
                median_s=f["median"],
                times_s=f["times"],
                cold_s=f["cold"],
                stages_best_s=f["stages_best"],
            )
            for k, f in fast.items()
        },
        naive={
            mode: dict(
                measured_realizations=K,
                extrapolated_to=R,
                extrapolated=K != R,
                total_s=t_naive[mode],
                runs_total_s=naive_times[mode],
                fixed_s=nv["t_fixed"],
                loop_s=nv["t_loop"],
                loop_identify_s=nv["t_ident"],
                loop_mpc_s=nv["t_mpc"],
                cpu_s=cpu_naive[mode],
            )
            for mode, nv in naive.items()
        },
        speedup=ratios,
        best_fast_s=best_fast,
        cli=None
        if cli is None
        else dict(
            runs=cli["runs"],
            best_s=cli["best"],
            median_s=cli["median"],
            cpu_median_s=cli["cpu_median"],
            engine_median_s=cli["engine_median"],
            same_result_as_engine=cli_same,
            naive_over_cli={mode: t_naive[mode] / cli["median"] for mode in modes},
            naive_cpu_over_cli_cpu={mode: cpu_naive[mode] / cli["cpu_median"] for mode in modes},
        ),
        targets=None
        if cli is None
        else dict(
            cli_le_3s=cli["median"] <= 3.0, naive_ge_20x={mode: t_naive[mode] / cli["median"] >= 20 for mode in modes}
        ),
        correctness=dict(
            **diffs, executor_max_abs_diff_AB=exec_diff, by_naive_mode={m: d for m, d in diffs_modes.items()}
        ),
        per_b=rows,
    )
    print("RESULT " + json.dumps(result))
    return result


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import _tee

    _tee.run(main, None)
