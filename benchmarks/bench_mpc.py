#!/usr/bin/env python
"""One MPC closed loop: the engine against cvxpy + OSQP and do-mpc + IPOPT on the same problem.

Problem (letter, eq. (2)): the true model of ``dc-motor`` / ``boeing747``, the
letter's x0, Q and R, horizon 10, 50 closed-loop steps, ``|u| <= u_max``,
``Qf`` = stabilizing DARE solution. Two cases per system:

* ``letter``: x0 and ``|u| <= 1`` as in the letter (the bound is never active:
  the engine's exact Riccati fast path answers every step);
* ``constrained``: ``20 * x0`` and ``|u| <= 0.3``, so the input bound is active
  and the engine solves those steps as a QP (DAQP / batched active set on the
  condensed problem; the previous engine's sparse OSQP path is timed alongside).

Solvers, each timed per closed loop (best and median of ``--repeats``):

* ``engine run_closed_loops``: :func:`qsid_core.control.closed_loop.run_closed_loops` on the single
  model, *including* building the controller (DARE, Riccati gains, condensing, DAQP setup);
* ``engine run_closed_loops, solver=osqp``: the same with the previous engine's OSQP path;
* ``engine MPCController.solve``: build :class:`qsid_core.control.controller.MPCController`, then
  ``solve(x)`` per step (also included);
* ``cvxpy + OSQP``: the QP built once with a Parameter for x0 (build and first
  compile reported separately, *not* included), solved every step with
  ``warm_start=True``; tight tolerances (eps 1e-9, polishing, as the engine) and,
  for reference, cvxpy's OSQP defaults;
* ``do-mpc + IPOPT``: do-mpc's MPC class with the same discrete linear model,
  horizon, weights, bounds and terminal cost (setup not included, output
  silenced); IPOPT's defaults and tightened tolerances.

Agreement: max |u_peer - u_engine| over the applied input sequences (target 1e-6).
Then the saturated stage of a sweep (``benchmarks/_mpc_stage.py``): every identified
Boeing model's saturated closed loop by the compiled loop against per-step OSQP loops
(target >= 100x), with the 1-minute load average beside every row (the machine is shared).

The last line is ``RESULT {json}``; ``--save FILE`` writes the output to FILE as well.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import statistics
import sys
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from dataclasses import replace

import numpy as np
from threadpoolctl import threadpool_info, threadpool_limits

from qsid_core import (
    MPCConfig,
    MPCController,
    get_system,
    run_closed_loops,
)
from qsid_core.control import dare_stabilizing


def blas_threads() -> dict:
    """Threads of each BLAS library loaded in this process (file name -> threads), by threadpoolctl."""
    return {
        i["filepath"].rsplit("/", 1)[-1]: int(i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas"
    }


def set_blas_threads(n: int = 1) -> None:
    """Limit every loaded BLAS to ``n`` threads for the rest of this process (also a pool initializer)."""
    threadpool_limits(limits=int(n), user_api="blas")


TOL = 1e-6  # required agreement of the applied inputs
TIGHT_EPS = 1e-9  # the engine's OSQP tolerance (MPCConfig.eps)


def cases(quick: bool = False) -> list[dict]:
    """The benchmark problems: (system, case name, x0 scale, u_max, horizon, steps)."""
    steps, horizon = (12, 5) if quick else (50, 10)
    systems = ("dc-motor",) if quick else ("dc-motor", "boeing747")
    out = []
    for s in systems:
        out.append(dict(system=s, case="letter", x0_scale=1.0, u_max=1.0, horizon=horizon, steps=steps))
        out.append(dict(system=s, case="constrained", x0_scale=20.0, u_max=0.3, horizon=horizon, steps=steps))
    return out


class Problem:
    """One closed-loop problem with everything resolved to arrays."""

    def __init__(self, system: str, case: str, x0_scale: float, u_max: float, horizon: int, steps: int):
        self.sys = get_system(system)
        self.name = f"{self.sys.name} {case}"
        self.case = case
        self.A, self.B = self.sys.A, self.sys.B
        self.n, self.m = self.B.shape
        self.Q, self.R = np.array(self.sys.Q), np.array(self.sys.R)
        self.x0 = np.array(self.sys.x0, dtype=float) * x0_scale
        self.u_max = np.full(self.m, float(u_max))
        self.N, self.steps = int(horizon), int(steps)
        self.cfg = MPCConfig(horizon=self.N, steps=self.steps, u_max=float(u_max), x0=tuple(self.x0), eps=TIGHT_EPS)
        self.Qf = dare_stabilizing(self.A, self.B, self.Q, self.R)  # handed to the peers (the engine computes its own)

    def describe(self) -> str:
        return (
            f"{self.name}: x0 = {np.array2string(self.x0, precision=3)}, |u| <= {self.u_max[0]:g}, "
            f"horizon {self.N}, {self.steps} steps"
        )


# ----------------------------------------------------------------------------------------------
# solvers: each returns a runner ``run() -> (inputs (steps, m), info dict)``
# ----------------------------------------------------------------------------------------------
def engine_loops(pb: Problem, solver: str = "daqp"):
    """:func:`run_closed_loops` on the single (true) model; builds its controller each call."""
    cfg = replace(pb.cfg, solver=solver)

    def run():
        lp = run_closed_loops([(pb.A, pb.B)], pb.A, pb.B, cfg, pb.sys)
        if lp.failure[0]:
            raise RuntimeError(f"engine failed: {lp.messages[0]}")
        return lp.inputs[0], dict(qp_steps=lp.qp_steps, fast_steps=pb.steps - lp.qp_steps)

    return run, 0.0


def engine_controller(pb: Problem):
    """Build :class:`MPCController` (DARE, gains) and call ``solve(x)`` every step."""

    def run():
        ctrl = MPCController(pb.A, pb.B, pb.Q, pb.R, pb.N, pb.u_max, eps=TIGHT_EPS)
        x = pb.x0.copy()
        us = np.empty((pb.steps, pb.m))
        nfast = 0
        for t in range(pb.steps):
            u, _, fast = ctrl.solve(x)
            nfast += bool(fast)
            us[t] = u
            x = pb.A @ x + pb.B @ u
        return us, dict(qp_steps=pb.steps - nfast, fast_steps=nfast)

    return run, 0.0


def cvxpy_osqp(pb: Problem, tight: bool = True):
    """cvxpy problem built once (Parameter x0), OSQP warm-started every step. Returns (run, setup seconds)."""
    import cvxpy as cp

    t0 = time.perf_counter()
    n, m, N = pb.n, pb.m, pb.N
    x = cp.Variable((N + 1, n))
    u = cp.Variable((N, m))
    x0 = cp.Parameter(n)
    cost = sum(cp.quad_form(x[k], pb.Q) + cp.quad_form(u[k], pb.R) for k in range(N)) + cp.quad_form(x[N], pb.Qf)
    cons = [x[0] == x0, x[1:] == x[:-1] @ pb.A.T + u @ pb.B.T, u <= pb.u_max[None, :], u >= -pb.u_max[None, :]]
    prob = cp.Problem(cp.Minimize(cost), cons)
    opts = dict(eps_abs=TIGHT_EPS, eps_rel=TIGHT_EPS, polishing=True, max_iter=20000) if tight else {}

    def solve(xm):
        x0.value = xm
        prob.solve(solver=cp.OSQP, warm_start=True, **opts)
        if prob.status not in ("optimal", "optimal_inaccurate"):
            raise RuntimeError(f"cvxpy/OSQP status {prob.status}")
        return np.asarray(u.value[0])

    solve(pb.x0)  # first solve: canonicalisation + OSQP setup (part of the setup time)
    setup = time.perf_counter() - t0

    def run():
        xm = pb.x0.copy()
        us = np.empty((pb.steps, m))
        for t in range(pb.steps):
            us[t] = solve(xm)
            xm = pb.A @ xm + pb.B @ us[t]
        return us, {}

    return run, setup


@contextlib.contextmanager
def _quiet():
    """Silence Python-level output and warnings (do-mpc's import notices, casadi's numpy notice)."""
    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore")
        yield


def do_mpc_ipopt(pb: Problem, tight: bool = True):
    """do-mpc MPC (discrete linear model, lterm x'Qx + u'Ru, mterm x'Qf x, input bounds), IPOPT."""
    with _quiet():
        import casadi as ca
        import do_mpc

        t0 = time.perf_counter()
        model = do_mpc.model.Model("discrete")
        x = model.set_variable("_x", "x", shape=(pb.n, 1))
        u = model.set_variable("_u", "u", shape=(pb.m, 1))
        model.set_rhs("x", ca.mtimes(ca.DM(pb.A), x) + ca.mtimes(ca.DM(pb.B), u))
        model.setup()
        mpc = do_mpc.controller.MPC(model)
        mpc.settings.n_horizon = pb.N
        mpc.settings.t_step = 1.0
        mpc.settings.store_full_solution = False
        mpc.settings.supress_ipopt_output()
        if tight:
            # IPOPT's defaults (tol 1e-8, bound_relax_factor 1e-8) leave u up to ~1e-8 outside an active bound
            mpc.settings.nlpsol_opts.update(
                {"ipopt.tol": 1e-12, "ipopt.bound_relax_factor": 0.0, "ipopt.mu_target": 1e-12}
            )
        mpc.set_objective(
            lterm=ca.mtimes([x.T, ca.DM(pb.Q), x]) + ca.mtimes([u.T, ca.DM(pb.R), u]),
            mterm=ca.mtimes([x.T, ca.DM(pb.Qf), x]),
        )
        mpc.bounds["lower", "_u", "u"] = -pb.u_max.reshape(-1, 1)
        mpc.bounds["upper", "_u", "u"] = pb.u_max.reshape(-1, 1)
        mpc.setup()
        setup = time.perf_counter() - t0

    def run():
        with _quiet():
            mpc.reset_history()
            mpc.x0 = pb.x0.reshape(-1, 1)
            mpc.set_initial_guess()
            xm = pb.x0.copy()
            us = np.empty((pb.steps, pb.m))
            for t in range(pb.steps):
                us[t] = np.asarray(mpc.make_step(xm.reshape(-1, 1))).ravel()
                st = mpc.solver_stats
                if not st.get("success", True):
                    raise RuntimeError(f"do-mpc/IPOPT: {st.get('return_status')}")
                xm = pb.A @ xm + pb.B @ us[t]
        return us, {}

    return run, setup


SOLVERS = {
    "engine run_closed_loops": lambda pb: engine_loops(pb),
    "engine run_closed_loops, solver=osqp": lambda pb: engine_loops(pb, "osqp"),
    "engine MPCController.solve": lambda pb: engine_controller(pb),
    "cvxpy+OSQP tight (eps 1e-9)": lambda pb: cvxpy_osqp(pb, tight=True),
    "cvxpy+OSQP cvxpy defaults": lambda pb: cvxpy_osqp(pb, tight=False),
    "do-mpc+IPOPT tight (tol 1e-12)": lambda pb: do_mpc_ipopt(pb, tight=True),
    "do-mpc+IPOPT defaults": lambda pb: do_mpc_ipopt(pb, tight=False),
}
ENGINE = ("engine run_closed_loops", "engine MPCController.solve", "engine run_closed_loops, solver=osqp")
PEER_FAMILY = {
    "cvxpy+OSQP tight (eps 1e-9)": "cvxpy",
    "cvxpy+OSQP cvxpy defaults": "cvxpy",
    "do-mpc+IPOPT tight (tol 1e-12)": "do-mpc",
    "do-mpc+IPOPT defaults": "do-mpc",
}


def available(name: str) -> bool:
    fam = PEER_FAMILY.get(name)
    if fam is None:
        return True
    try:
        with _quiet():
            __import__("cvxpy" if fam == "cvxpy" else "do_mpc")
    except ImportError:
        return False
    return True


def _time(run, repeats: int):
    times, us, info = [], None, {}
    for _ in range(repeats):
        t0 = time.perf_counter()
        us, info = run()
        times.append(time.perf_counter() - t0)
    return times, us, info


def benchmark_problem(pb: Problem, solvers, repeats_engine: int, repeats_peer: int) -> dict:
    """Time every solver on ``pb``; inputs are compared with ``engine run_closed_loops``."""
    out = {}
    for name in solvers:
        run, setup = SOLVERS[name](pb)
        run()  # warm-up (first calls, lazy imports), not timed
        times, us, info = _time(run, repeats_engine if name in ENGINE else repeats_peer)
        out[name] = dict(times=times, best=min(times), median=statistics.median(times), setup=setup, inputs=us, **info)
    ref = out[ENGINE[0]]["inputs"]
    for r in out.values():
        r["max_abs_du"] = float(np.abs(r["inputs"] - ref).max())
    return out


def check_agreement(quick: bool = True, solvers=None) -> dict:
    """Max |du| against the engine for every (case, solver) (used by the smoke test; one repeat, no timing use)."""
    solvers = [s for s in (solvers or SOLVERS) if available(s)]
    res = {}
    for c in cases(quick):
        pb = Problem(**c)
        r = benchmark_problem(pb, solvers, 1, 1)
        res[pb.name] = {k: dict(max_abs_du=v["max_abs_du"], qp_steps=v.get("qp_steps")) for k, v in r.items()}
    return res


def _main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="dc-motor only, horizon 5, 12 steps, 1 repeat")
    ap.add_argument("--repeats", type=int, default=None, help="timed closed loops per peer (default 5; quick 1)")
    ap.add_argument(
        "--engine-repeats", type=int, default=None, help="timed closed loops per engine variant (default 50; quick 3)"
    )
    ap.add_argument("--skip", default="", help="comma-separated parts to skip: cvxpy, do-mpc, stage")
    ap.add_argument(
        "--stage-realizations", type=int, default=None, help="dither realizations per b in the stage (default 10)"
    )
    ap.add_argument("--stage-repeats", type=int, default=None, help="timed stages, compiled rows (default 5)")
    ap.add_argument("--osqp-repeats", type=int, default=None, help="timed stages, OSQP rows (default 2)")
    ap.add_argument(
        "--blas-threads",
        type=int,
        default=None,
        help="set OpenBLAS threads of this process first (default: leave the environment's setting)",
    )
    args = ap.parse_args(argv)
    rp = args.repeats if args.repeats is not None else (1 if args.quick else 5)
    re_ = args.engine_repeats if args.engine_repeats is not None else (3 if args.quick else 50)
    skip = {s.strip() for s in args.skip.split(",") if s.strip()}
    solvers = [s for s in SOLVERS if PEER_FAMILY.get(s) not in skip and available(s)]
    missing = [s for s in SOLVERS if PEER_FAMILY.get(s) not in skip and not available(s)]
    if args.blas_threads is not None:  # after the peers' imports, which may load their own OpenBLAS
        set_blas_threads(args.blas_threads)

    print(
        f"QSID MPC closed-loop benchmark ({'quick' if args.quick else 'full'}); {os.cpu_count()} shared cores, "
        f"best/median of {re_} (engine) / {rp} (peers) closed loops"
    )
    print(
        "engine times include building the controller (DARE, gains, QP setup); peer times exclude their setup "
        "(shown separately)"
    )
    print(
        f"OpenBLAS threads in this process: {blas_threads() or 'unknown'}; load average {'/'.join(f'{x:.1f}' for x in os.getloadavg())}"
    )
    if missing:
        print("not installed, skipped:", ", ".join(missing))
    results = []
    ok_all = True
    for c in cases(args.quick):
        pb = Problem(**c)
        r = benchmark_problem(pb, solvers, re_, rp)
        eng_best = r[ENGINE[0]]["best"]
        print()
        print(pb.describe())
        print(
            f"  {'solver':<38}{'best [ms]':>11}{'median [ms]':>13}{'setup [ms]':>12}{'fast/QP':>11}"
            f"{'max|du| vs engine':>19}{'time / engine':>15}"
        )
        for name, v in r.items():
            steps = f"{v['fast_steps']}/{v['qp_steps']}" if "qp_steps" in v else "-"
            ratio = v["best"] / eng_best
            agree = v["max_abs_du"] <= TOL
            if "defaults" not in name:  # the defaults rows are for reference: tight rows must agree
                ok_all &= agree
            print(
                f"  {name:<38}{v['best'] * 1e3:>11.3f}{v['median'] * 1e3:>13.3f}"
                f"{(v['setup'] * 1e3 if v['setup'] else 0):>12.1f}{steps:>11}{v['max_abs_du']:>19.2e}"
                f"{ratio:>14.1f}x{'' if agree else '  (> 1e-6: defaults too loose)'}"
            )
        results.append(
            dict(
                problem=pb.name,
                system=pb.sys.name,
                case=pb.case,
                x0=pb.x0.tolist(),
                u_max=float(pb.u_max[0]),
                horizon=pb.N,
                steps=pb.steps,
                solvers={
                    k: dict(
                        best_s=v["best"],
                        median_s=v["median"],
                        times_s=v["times"],
                        setup_s=v["setup"],
                        max_abs_du=v["max_abs_du"],
                        qp_steps=v.get("qp_steps"),
                        fast_steps=v.get("fast_steps"),
                        speedup_vs_engine=v["best"] / eng_best,
                    )
                    for k, v in r.items()
                },
            )
        )

    print()
    print("summary: peer time / engine time (target: engine >= 30x faster than cvxpy+OSQP on the constrained rows)")
    targets = {}
    for res in results:
        sv = res["solvers"]
        for peer in ("cvxpy+OSQP tight (eps 1e-9)", "do-mpc+IPOPT tight (tol 1e-12)"):
            if peer not in sv:
                continue
            r = {e: sv[peer]["best_s"] / sv[e]["best_s"] for e in ENGINE}
            best = max(r[ENGINE[0]], r[ENGINE[1]])
            targets[f"{res['problem']} / {peer}"] = dict(
                vs_run_closed_loops=r[ENGINE[0]],
                vs_controller_solve=r[ENGINE[1]],
                vs_old_osqp_engine=r[ENGINE[2]],
                met=best >= 30,
            )
            print(
                f"  {res['problem']:<24} {peer:<32}: {r[ENGINE[0]]:6.1f}x (run_closed_loops)  "
                f"{r[ENGINE[1]]:6.1f}x (MPCController.solve)  [old OSQP engine {r[ENGINE[2]]:5.1f}x]  "
                f"{'MET' if best >= 30 else 'NOT met'}"
            )
    print(f"engine and tight-tolerance peers agree on the applied inputs to {TOL:g}: {'yes' if ok_all else 'NO'}")
    loose = sorted(
        {
            f"{k} ({res['problem']}: {v['max_abs_du']:.1e})"
            for res in results
            for k, v in res["solvers"].items()
            if "defaults" in k and v["max_abs_du"] > TOL
        }
    )
    if loose:
        print("with their default tolerances these peers miss 1e-6 (hence the tightened rows): " + "; ".join(loose))
    stage = None
    if "stage" not in skip:
        import _mpc_stage

        stage = _mpc_stage.stage(
            args.quick,
            args.stage_realizations or (2 if args.quick else 10),
            args.stage_repeats or (1 if args.quick else 5),
            args.osqp_repeats or (1 if args.quick else 2),
        )
        ok_all &= _mpc_stage.report(stage, TOL)
    out = dict(
        benchmark="bench_mpc",
        loadavg=os.getloadavg(),
        saturated_stage=stage,
        quick=bool(args.quick),
        cores=os.cpu_count(),
        blas_threads=blas_threads(),
        tolerance=TOL,
        repeats_engine=re_,
        repeats_peer=rp,
        problems=results,
        all_agree=ok_all,
        targets_30x=targets,
    )
    print("RESULT " + json.dumps(out))
    return out


def main(argv=None):
    """Run the benchmark; ``--save FILE`` also writes the printed output to FILE (header first)."""
    import _tee

    return _tee.run(_main, argv)


if __name__ == "__main__":
    main()
