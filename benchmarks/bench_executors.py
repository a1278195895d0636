"""Process pools side by side for the dashboard and ``qsid --workers``: start-up, and a dashboard view through each.

For each kind of executor of ``--workers`` processes (default 2), in one run: the seconds until every worker has
answered a task (imports done), the first default dashboard view computed through it (the workers load the
kernels on their first tasks), the median of three more (a fresh results cache each), the paper-scale view, and
the seconds to stop it. Kinds:

* ``loky``: ``loky.ProcessPoolExecutor``, what :func:`app.procs.process_pool` makes;
* ``stdlib``: ``concurrent.futures.ProcessPoolExecutor`` with the "spawn" context (as the workers are fresh
  interpreters in the other kinds);
* ``dask``: a dask.distributed ``LocalCluster`` of single-threaded worker processes through
  :class:`app.distributed.DaskExecutor` (the ``distributed`` extra);
* ``dashboard``: ``app.dashboard.pool.Pool(N).guarded()``, the pool as a tab uses it, of the checkout on
  ``PYTHONPATH`` (up to commit 8099aa3 the home-made ``app.procs.ProcessPool``, the data every task needs
  shared through a file; since, loky's with the watchdog).

Usage::

    python benchmarks/bench_executors.py                          # dashboard loky stdlib dask
    PYTHONPATH=OLD_CHECKOUT python benchmarks/bench_executors.py  # the same with the old dashboard pool
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time


def first_answers(ex, n: int) -> None:
    """Return once each of the ``n`` workers of ``ex`` has answered a task (its imports done)."""
    seen: set[int] = set()
    while len(seen) < n:
        seen |= {f.result() for f in [ex.submit(os.getpid) for _ in range(n)]}
        time.sleep(0.05)


def make(kind: str, n: int):
    """``(executor, stop)`` of ``kind`` with ``n`` workers, BLAS at one thread in each (as the dashboard's)."""
    from app.dashboard.lifecycle import one_blas_thread

    if kind == "loky":
        import loky

        return loky.ProcessPoolExecutor(n, initializer=one_blas_thread), lambda ex: ex.shutdown(kill_workers=True)
    if kind == "stdlib":
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        ctx = multiprocessing.get_context("spawn")
        return ProcessPoolExecutor(n, mp_context=ctx, initializer=one_blas_thread), lambda ex: ex.shutdown()
    if kind == "dashboard":  # the dashboard's pool as a tab uses it
        from app.dashboard.pool import Pool

        pool = Pool(n, 600.0)
        return pool.guarded(), lambda ex: pool.shutdown()
    if kind == "dask":
        import logging

        from distributed import Client, LocalCluster

        from app.distributed import DaskExecutor

        cluster = LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
            silence_logs=logging.ERROR,
        )
        client = Client(cluster)
        client.run(one_blas_thread)
        return DaskExecutor(client), lambda ex: (ex.shutdown(), client.close(), cluster.close())
    raise SystemExit(f"unknown kind {kind!r}")


def view(values, ex, tasks: int) -> float:
    """Seconds to compute and draw a tab's frames of ``values`` through ``ex`` into an empty cache."""
    from app.dashboard.lifecycle import prefill
    from app.frames.cache import SharedCache

    t = time.perf_counter()
    prefill(values, SharedCache(), ex, tasks)
    return time.perf_counter() - t


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--kinds", default="dashboard,loky,stdlib,dask", help="comma-separated: dashboard, loky, stdlib, dask"
    )
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-paper", action="store_true", help="skip the paper-scale view")
    a = ap.parse_args(argv)
    from app.dashboard.lifecycle import one_blas_thread, warm_here
    from app.settings.values import INTERACTIVE, PAPER_SCALE, Values

    one_blas_thread()
    warm_here()  # the kernels compiled (or loaded) here, so no kind pays the compiler
    interactive = Values(system="dc-motor").replace(**INTERACTIVE)
    paper = Values(system="dc-motor").replace(**PAPER_SCALE)
    rows = [{"kind": "in-process", "view_s": round(statistics.median(view(interactive, None, 1) for _ in range(3)), 3)}]
    print("RESULT", json.dumps(rows[-1]), flush=True)
    for kind in a.kinds.split(","):
        t = time.perf_counter()
        ex, stop = make(kind, a.workers)
        first_answers(ex, a.workers)
        row: dict = {"kind": kind, "start_s": round(time.perf_counter() - t, 2)}
        row["first_view_s"] = round(view(interactive, ex, a.workers), 2)
        row["view_s"] = round(statistics.median(view(interactive, ex, a.workers) for _ in range(3)), 3)
        if not a.no_paper:
            row["paper_view_s"] = round(view(paper, ex, a.workers), 2)
        t = time.perf_counter()
        stop(ex)
        row["stop_s"] = round(time.perf_counter() - t, 3)
        row["load"] = round(os.getloadavg()[0], 1)
        rows.append(row)
        print("RESULT", json.dumps(row), flush=True)
    return rows


if __name__ == "__main__":
    main()
