"""How fast does the dashboard redraw? Measured with its pure update function, no browser.

Times what a browser tab's worker does for one change of settings:
:func:`app.dashboard.session.iter_frames` (engine work, shared cache) plus
:class:`app.frames.render.Renderer` (3-D arrays, summary, plotly figures)
plus serialising every changed figure to JSON (what viser sends). Network and
browser rendering are not included.

Targets (issue 9 supersedes the dashboard issue's; each row prints its target and
whether the measured median meets it):

* interactive default (50 x 200 samples, 20 realizations): ANY single change
  (b, Q/R, data, and the saturated-MPC what-if: Boeing 747, x0 = 20*[1,1,0,0],
  input bound 1 -> 0.3 and -> 0.2) draws all curves within 0.5 s (a b change
  also within the older 100 ms);
* paper scale (200 x 1000, 50 realizations): a data change draws all curves
  within 1.5 s.

Usage::

    python benchmarks/bench_dashboard.py                # the dashboard's own process pool of 2 (app.dashboard.pool)
    python benchmarks/bench_dashboard.py --workers 0    # everything in-process
    python benchmarks/bench_dashboard.py --pool thread  # a thread pool of 2 (the kernels release the GIL)
    python benchmarks/bench_dashboard.py --no-paper     # interactive only
    python benchmarks/bench_dashboard.py --save out.txt # also write the output to out.txt (docs/perf/)

Every row prints the 1-minute load average while it ran (the machine is shared). With
``--workers 0`` (everything in this process) each row is followed by where its CPU time
went: identification, closed loops, bounds, figure building, serialisation and the
rest (``benchmarks/_breakdown.py``).

Numbers are printed, never hard-coded; they depend on the machine and its load.
"CPU ms" is this process's CPU time per change (all its threads; a process pool's
workers are not included): on a loaded machine it shows what the change costs,
while the wall times show what a person waited.
"""

from __future__ import annotations

import os
import sys

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):  # as qsid-dashboard does
    os.environ.setdefault(_var, "1")

import argparse
import statistics
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np
from _breakdown import Breakdown, line

from app.dashboard.session import iter_frames
from app.frames.cache import SharedCache
from app.frames.render import Renderer
from app.settings.values import INTERACTIVE, PAPER_SCALE, Values, log_from_weights, resolve_system

#: the CPU breakdown while the benchmark runs in-process (None with a pool)
BREAKDOWN: Breakdown | None = None


def update(values: Values, cache, renderer: Renderer, executor, tasks: int, memo: dict | None = None) -> dict:
    """One change of settings, as a tab's worker handles it (``renderer`` and ``memo``: the tab's); returns
    seconds to the current b and to all curves."""
    if BREAKDOWN is not None:
        BREAKDOWN.reset()
    t0, c0 = time.perf_counter(), time.process_time()
    out = {"load": os.getloadavg()[0]}
    for frame in iter_frames(values, cache, executor, tasks, memo=memo):
        r = renderer.render(frame, values.axes)
        for fig in r.figures.values():
            fig.to_json()
        if frame.stage == "current":
            out["current"] = time.perf_counter() - t0
    out["all"] = time.perf_counter() - t0
    out["cpu"] = time.process_time() - c0  # this process's threads only (not a process pool's workers)
    if BREAKDOWN is not None:
        out["breakdown"] = dict(BREAKDOWN.cpu)
    return out


def per_view(values: Values, cache, bits: list, executor, tasks: int, pinned=None) -> dict:
    """CPU milliseconds (this process) to build + serialise each registered view, per b.

    CPU time, not wall time: on a shared, loaded machine wall times of a few ms are
    mostly waiting; the CPU time is what the view costs.

    The renderer redraws only the views whose inputs changed; this times every
    view on the last frame of each b (cached engine results), so a view's cost is
    visible even when it is in a tab the person is not looking at.
    """
    from app.figures import registry
    from app.figures.compare import PINNED_VIEWS, overlay_pinned

    out: dict = {v.name: [] for v in registry.VIEWS}
    for b in bits:
        frame = list(iter_frames(values.replace(bits=b), cache, executor, tasks))[-1]
        for v in registry.VIEWS:
            t = time.process_time()
            fig = v.build(frame)
            if pinned is not None and v.name in PINNED_VIEWS:
                overlay_pinned(fig, v.build(pinned), "pinned")
            fig.to_json()
            out[v.name].append(1000 * (time.process_time() - t))
    return out


def _median(runs: list, key: str) -> float:
    return statistics.median(r[key] for r in runs)


def _row(name: str, runs: list, target: str, limit_ms: float | None = None) -> None:
    """One printed row; with ``limit_ms`` the median of "all curves" is compared with the target."""
    cur = [r["current"] * 1000 for r in runs]
    tot = [r["all"] * 1000 for r in runs]
    verdict = "" if limit_ms is None else ("  MET" if statistics.median(tot) <= limit_ms else "  NOT MET")
    load = [r["load"] for r in runs]
    print(
        f"{name:<42} {statistics.median(cur):8.0f} {min(cur):8.0f} {max(cur):8.0f}   "
        f"{statistics.median(tot):8.0f} {min(tot):8.0f} {max(tot):8.0f}   "
        f"{statistics.median(r['cpu'] * 1000 for r in runs):6.0f}   {min(load):4.1f}-{max(load):<4.1f}  "
        f"{target}{verdict}",
        flush=True,
    )
    if all("breakdown" in r for r in runs):
        bd = Breakdown()
        for r in runs:
            for k, v in r["breakdown"].items():
                bd.cpu[k] += v
        print(f"  CPU ms per change: {line(bd, sum(r['cpu'] for r in runs), len(runs))}", flush=True)


#: The saturated-MPC what-if of issue 9 (the Boeing's input bound made active).
SATURATED = dict(system="boeing747", x0="20, 20, 0, 0")


def saturated_runs(base: Values, cache, renderer: Renderer, executor, tasks: int, repeat: int, memo=None) -> list:
    """Bound 1 -> 0.3 and 1 -> 0.2 on the Boeing from x0 = 20*[1,1,0,0], each a fresh data seed (no cache help)."""
    runs = []
    for i in range(repeat):
        v = base.replace(**SATURATED, u_max=1.0, data_seed=300 + i)
        update(v, cache, renderer, executor, tasks, memo)  # the unsaturated view the person starts from
        runs.append(update(v.replace(u_max=(0.3, 0.2)[i % 2]), cache, renderer, executor, tasks, memo))
    return runs


def _main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--workers", type=int, default=2, help="pool size (0 = in-process)")
    p.add_argument("--pool", default="process", choices=("process", "thread"), help="kind of pool")
    p.add_argument("--repeat", type=int, default=5, help="changes timed per case (median, min, max shown)")
    p.add_argument("--no-paper", action="store_true", help="skip the paper-scale case")
    p.add_argument("--system", default="dc-motor")
    p.add_argument("--datalength", action="store_true", help="also time the data-length study (tens of seconds)")
    p.add_argument("--identification", default="LS + BCLS", choices=("LS", "BCLS", "LS + BCLS"))
    a = p.parse_args(argv)
    from app.dashboard.lifecycle import one_blas_thread

    one_blas_thread()  # as the server does at start
    ex = pool = None
    if a.workers and a.pool == "thread":
        ex = ThreadPoolExecutor(a.workers)
    elif a.workers:  # the dashboard's own pool, as a tab uses it (data shared once per worker, watched tasks)
        from app.dashboard.lifecycle import warm
        from app.dashboard.pool import Pool

        pool = Pool(a.workers)
        ex = pool.guarded()
        for f in [ex.submit(abs, 0) for _ in range(a.workers)]:
            f.result()
        warm(pool)  # as the server does before it says it is ready: kernels compiled or loaded in every worker
    tasks = max(1, a.workers)
    global BREAKDOWN
    if not a.workers:
        BREAKDOWN = Breakdown().__enter__()
    print(
        f"qsid dashboard update latency · system {a.system} · {a.identification} · "
        f"{a.pool + ' pool of ' + str(a.workers) if a.workers else 'in-process'} · "
        f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}"
    )
    print(
        f"{'change':<42} {'current b [ms]: median':>24} {'min':>4} {'max':>8}   "
        f"{'all curves [ms]: median':>8} {'min':>4} {'max':>8}   {'CPU ms':>6}   {'load':>9}  target"
    )
    cache = SharedCache()
    ren, memo = Renderer(), {}  # one tab's renderer and summary rows
    base = Values(system=a.system, identification=a.identification, **INTERACTIVE)
    cold = [update(base, cache, ren, ex, tasks, memo)]
    _row("interactive: first view (cold cache)", cold, "-")
    bits = [5, 6, 3, 7, 4, 8, 2, 9, 10, 11]
    runs = [update(base.replace(bits=b), cache, ren, ex, tasks, memo) for b in bits[: a.repeat]]
    _row("interactive: b change", runs, "<= 100 ms (all, dashboard issue); issue 9: <= 500 ms", 100)
    pinned = list(iter_frames(base.replace(dither="none"), cache, ex, tasks))[-1]
    for label, pin in (("", None), (" + pinned overlay", pinned)):
        views = per_view(base, cache, bits[: a.repeat], ex, tasks, pin)
        print(
            f"  per view, build + JSON{label} [CPU ms] (median min max over {a.repeat} b): "
            + " · ".join(f"{k} {statistics.median(x):.0f} {min(x):.0f} {max(x):.0f}" for k, x in views.items())
        )
    v = base.replace(bits=bits[a.repeat - 1] if a.repeat <= len(bits) else 4)
    sysm = resolve_system(v).system
    lq, lr = log_from_weights(np.diag(sysm.Q)), log_from_weights(np.diag(sysm.R))
    runs = []
    for i in range(a.repeat):  # move the first Q and the last R slider, as a person would
        d = 0.1 * (i + 1)
        runs.append(
            update(v.replace(log_q=(lq[0] + d,) + lq[1:], log_r=lr[:-1] + (lr[-1] - d,)), cache, ren, ex, tasks, memo)
        )
    _row("interactive: Q/R change", runs, "<= 500 ms (all)", 500)
    runs = [update(v.replace(data_seed=100 + i), cache, ren, ex, tasks, memo) for i in range(a.repeat)]
    _row("interactive: data change (seed)", runs, "<= 500 ms (all)", 500)
    runs = saturated_runs(base, cache, ren, ex, tasks, a.repeat, memo)
    _row("interactive: saturated MPC (boeing |u|<=.3/.2)", runs, "<= 500 ms (all)", 500)
    if not a.no_paper:
        paper = base.replace(**PAPER_SCALE)
        update(paper, cache, ren, ex, tasks, memo)  # the dashboard's paper-scale button, once
        runs = [
            update(paper.replace(data_seed=200 + i), cache, ren, ex, tasks, memo) for i in range(max(2, a.repeat // 2))
        ]
        _row("paper scale: data change (seed)", runs, "<= 1500 ms (all)", 1500)
        runs = [update(paper.replace(data_seed=200, bits=b), cache, ren, ex, tasks, memo) for b in bits[: a.repeat]]
        _row("paper scale: b change", runs, "-")
    print(f"cache: {len(cache)} entries, ~{cache.nbytes / 2**20:.0f} MB, {cache.kinds()}")
    if a.datalength:
        from app.frames.datalength import datalength_config
        from qsid_core import run_datalength

        cfg = datalength_config(base)
        t = time.perf_counter()
        res = run_datalength(cfg, None, None, tasks=cfg.realizations)
        print(
            f"data-length study (dashboard button, in-process, {cfg.realizations} realizations, "
            f"{len(res.rows)} lengths up to {res.rows[-1].samples} samples): {time.perf_counter() - t:.1f} s"
        )
    if ex is not None:
        (pool if a.pool == "process" else ex).shutdown()
    if BREAKDOWN is not None:
        BREAKDOWN.__exit__(None, None, None)
        BREAKDOWN = None
    return 0


def main(argv=None):
    """Run the benchmark; ``--save FILE`` also writes the printed output to FILE (header first)."""
    import _tee

    return _tee.run(_main, argv)


if __name__ == "__main__":
    sys.exit(main())
