#!/usr/bin/env python
"""What running a sweep through dask.distributed costs on one machine.

The same paper-scale sweep (``SweepConfig()`` defaults: DC motor, 200 x 1000
samples, b = 1..16, 50 realizations, LS, MPC closed loops) is run

* in-process (``InlineExecutor``);
* with a ``ProcessPoolExecutor(2)`` (what ``qsid sweep --workers 2`` uses);
* on a dask ``LocalCluster`` of 2 single-threaded worker processes through
  :class:`app.distributed.DaskExecutor`, with ``share`` (the prepared data
  travels once per worker) and without it (shipped with every task).

Each executor is started once (its start-up is timed separately), then the sweep
runs ``--repeats`` times; the first (cold) run and the best run are printed per
stage (the engine's ``timing_s``). Every run's JSON (timings removed) must equal
the in-process one; the script says so. The bytes that travel to the workers for
the moments stage are computed from the pickled prepared data.

Run ``python benchmarks/bench_distributed.py`` (paper scale) or ``--quick``.
The last line is ``RESULT {json}`` with every measured number.
"""

from __future__ import annotations

import argparse
import json
import math
import pickle
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from threadpoolctl import threadpool_limits

from qsid_core import Experiment, InlineExecutor, SweepConfig, run_sweep


def set_blas_threads(n: int = 1) -> None:
    """Limit BLAS to ``n`` threads in this process (pool initializer; threadpoolctl does the work)."""
    threadpool_limits(limits=int(n), user_api="blas")


QUICK = dict(bits=(1, 4, 8, 12), realizations=8, trajectories=20, steps=300)
STAGES = ("data", "identify", "theory", "mpc", "total")


def _json(res) -> str:
    d = res.to_dict()
    d.pop("timing_s")
    return json.dumps(d, sort_keys=True)


def run_mode(name, open_executor, cfg, repeats, tasks, reference):
    """Start the executor (timed), run the sweep ``repeats`` times; returns the measured numbers."""
    t0 = time.perf_counter()
    with open_executor() as ex:
        startup = time.perf_counter() - t0
        runs = []
        same = True
        for _ in range(repeats):
            t1 = time.perf_counter()
            res = run_sweep(cfg, ex, tasks=tasks)
            wall = time.perf_counter() - t1
            runs.append(dict(res.timing_s, wall=round(wall, 4)))
            same &= reference is None or _json(res) == reference
            out_json = _json(res)
    best = min(runs, key=lambda r: r["total"])
    return {
        "mode": name,
        "startup_s": round(startup, 3),
        "cold": runs[0],
        "best": best,
        "identical": same,
        "json": out_json,
    }


def transport_probe(prep, workers: int, k: int) -> dict:
    """Seconds per trivial task that takes the prepared data, shipped with the task vs shared once.

    The task is the builtin ``id`` (importable on every worker): its time is the
    cost of getting the data to the worker and the result back.
    """
    from app.dask_cluster import make_executor

    out = {}
    with make_executor(f"local:{workers}") as ex:
        [f.result() for f in [ex.submit(id, 0) for _ in range(2 * workers)]]  # warm the workers
        t0 = time.perf_counter()
        [f.result() for f in [ex.submit(id, prep) for _ in range(k)]]
        out["per_task_shipped_s"] = (time.perf_counter() - t0) / k
        t0 = time.perf_counter()
        ref = ex.share(prep)
        out["share_once_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        [f.result() for f in [ex.submit(id, ref) for _ in range(k)]]
        out["per_task_shared_s"] = (time.perf_counter() - t0) / k
    t0 = time.perf_counter()
    for _ in range(k):
        pickle.loads(pickle.dumps(prep, protocol=5))
    out["pickle_roundtrip_s"] = (time.perf_counter() - t0) / k
    return {key: round(v, 5) for key, v in out.items()}


class _Closing:
    """``with`` for executors that only have shutdown()."""

    def __init__(self, ex):
        self.ex = ex

    def __enter__(self):
        return self.ex

    def __exit__(self, *exc):
        self.ex.shutdown(wait=True)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="tiny sizes (smoke test)")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--tasks", type=int, default=4, help="chunks the realizations are split into")
    ap.add_argument("--probe-tasks", type=int, default=20, help="tasks of the transport probe")
    a = ap.parse_args(argv)
    from app.dask_cluster import make_executor

    cfg = SweepConfig(**QUICK) if a.quick else SweepConfig()
    prep = Experiment(cfg).prepared
    prep_bytes = len(pickle.dumps(prep, protocol=5))
    n_tasks = math.ceil(cfg.realizations / math.ceil(cfg.realizations / min(a.tasks, cfg.realizations)))
    print(
        f"sweep: {cfg.trajectories} x {cfg.steps} samples, b = {cfg.bits[0]}..{cfg.bits[-1]}, "
        f"{cfg.realizations} realizations, MPC on; prepared data {prep_bytes / 1e6:.2f} MB pickled, "
        f"{n_tasks} moment tasks, {a.workers} workers"
    )

    w = a.workers
    modes = [
        ("in-process", lambda: _Closing(InlineExecutor())),
        (
            f"ProcessPoolExecutor({w})",
            lambda: _Closing(ProcessPoolExecutor(w, initializer=set_blas_threads, initargs=(1,))),
        ),
        (f"dask LocalCluster({w}) + share", lambda: make_executor(f"local:{w}")),
        (f"dask LocalCluster({w}), no share", lambda: make_executor(f"local:{w}", share_data=False)),
    ]
    results, reference = [], None
    for name, opener in modes:
        r = run_mode(name, opener, cfg, a.repeats, a.tasks, reference)
        reference = reference or r["json"]
        r["identical"] = r["identical"] and r["json"] == reference
        r.pop("json")
        results.append(r)

    head = f"{'executor':34s} {'start-up':>9s} " + " ".join(f"{s:>9s}" for s in STAGES) + "  (best of runs; cold total)"
    print(head)
    base = results[0]["best"]["total"]
    for r in results:
        b = r["best"]
        print(
            f"{r['mode']:34s} {r['startup_s']:8.2f}s "
            + " ".join(f"{b[s]:8.2f}s" for s in STAGES)
            + f"  cold {r['cold']['total']:.2f}s, x{b['total'] / base:.2f} of in-process, "
            + ("identical" if r["identical"] else "DIFFERENT")
        )
    # share: client -> scheduler once, scheduler -> one worker, then one copy per other worker;
    # no share: every task's graph carries it client -> scheduler -> worker
    shipped = {"share": (1 + w) * prep_bytes, "no_share": 2 * n_tasks * prep_bytes}
    print(
        f"prepared data moved for the moments stage: {shipped['share'] / 1e6:.1f} MB with share "
        f"(to the scheduler once, then once per worker) vs {shipped['no_share'] / 1e6:.1f} MB without "
        f"(client -> scheduler -> worker for each of {n_tasks} tasks)"
    )
    probe = transport_probe(prep, w, a.probe_tasks)
    print(
        f"transport probe ({a.probe_tasks} do-nothing tasks taking the prepared data, dask LocalCluster({w})): "
        f"{probe['per_task_shipped_s'] * 1e3:.1f} ms per task shipped with it, "
        f"{probe['per_task_shared_s'] * 1e3:.1f} ms per task after one share() of "
        f"{probe['share_once_s'] * 1e3:.1f} ms; pickle round trip {probe['pickle_roundtrip_s'] * 1e3:.1f} ms"
    )
    result = {
        "probe": probe,
        "config": {
            "trajectories": cfg.trajectories,
            "steps": cfg.steps,
            "bits": list(cfg.bits),
            "realizations": cfg.realizations,
        },
        "workers": w,
        "tasks": n_tasks,
        "prep_bytes": prep_bytes,
        "bytes_shipped": shipped,
        "runs": results,
    }
    print("RESULT " + json.dumps(result))
    return result


if __name__ == "__main__":
    main()
