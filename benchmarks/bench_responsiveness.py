"""How soon does the dashboard give way? Three waits a person notices, measured on a real server.

1. **Newer settings win**: a tab computes the largest settings the panel allows, then a person picks small
   ones; seconds until the small ones are drawn (target: a few seconds; it was 8.4 s when abandoned pool
   tasks of a whole pass kept the workers busy). Measured twice: during the current-b stage (after 0.5 s)
   and during the curves (after 4 s).
2. **Ctrl+C**: three tabs compute saturated settings with the process pool busy; seconds from SIGINT until
   the server process has ended (target: 2 s).
3. **Abandoned pool work**: a pool task that would run for minutes; seconds from "newer settings" until
   the caller is released (target: well under 1 s).

The server runs as ``python -m app.dashboard`` on 127.0.0.1 with a pool of ``--workers`` processes, driven
by plain websocket tabs (:mod:`_wsclient`). Numbers are printed (and written with ``--json``), never
asserted: on a shared, busy machine they are what they are. The tests
(``tests/system/test_dashboard_load.py``, ``tests/system/test_dashboard_process.py``, ``tests/dashboard/test_dashboard_faults.py``)
check the same behaviour without a clock.

Usage::

    python benchmarks/bench_responsiveness.py [--repeat 3] [--workers 2] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
for _p in (str(ROOT), str(HERE)):
    if _p not in sys.path:
        sys.path.insert(0, _p)
from _wsclient import WsTab
from bench_soak import Server

#: The largest settings the panel allows (panel label -> value).
HEAVY = {"realizations": 100, "trajectories": 400, "steps": 2000, "horizon": 50, "closed-loop steps": 300}
LIGHT = {"realizations": 4, "trajectories": 10, "steps": 60, "horizon": 10, "closed-loop steps": 15}
WAIT_S = 600.0  # give up on one measurement after this long (recorded as NaN)


def _send_all(tab: WsTab, values: dict, bits: int) -> None:
    for label, value in values.items():
        tab.send(label, value)
    tab.send("word length b", bits)


def _ready_after(tab: WsTab) -> float:
    try:
        return tab.wait_ready(WAIT_S)
    except (TimeoutError, ConnectionError):
        return float("nan")


def newer_settings_win(workers: int, delays=(0.5, 4.0)) -> dict:
    """Seconds until light settings are drawn after heavy ones ran for each of ``delays`` seconds."""
    server = Server("--workers", str(workers))
    out = {}
    try:
        tab = WsTab(server.url, WAIT_S)
        try:
            tab.wait_for("closed-loop steps", WAIT_S)
            _ready_after(tab)
            for i, delay in enumerate(delays):
                _send_all(tab, HEAVY, 5 + i)
                time.sleep(delay)
                still_heavy = not tab.ready
                t0 = time.monotonic()
                _send_all(tab, LIGHT, 5 + i)
                time.sleep(0.05)  # the status says "computing" once the light settings arrived
                waited = _ready_after(tab)
                out[f"light_after_{delay:g}s_heavy_s"] = (
                    waited if math.isnan(waited) else round(time.monotonic() - t0, 2)
                )
                out[f"heavy_still_running_at_{delay:g}s"] = still_heavy
        finally:
            tab.close()
    finally:
        out["server_stop_s"] = round(server.stop(WAIT_S), 2)
    return out


def ctrl_c_during_work(workers: int, tabs: int = 3, busy: float = 4.0) -> dict:
    """Seconds from SIGINT until the server ended while ``tabs`` tabs compute the heaviest settings."""
    server = Server("--workers", str(workers))
    clients = []
    try:
        clients = [WsTab(server.url, WAIT_S) for _ in range(tabs)]
        for i, t in enumerate(clients):
            t.wait_for("closed-loop steps", WAIT_S)
            _send_all(t, HEAVY, 3 + i)
        time.sleep(busy)
        still = sum(not t.ready for t in clients)
    finally:
        took = server.stop(WAIT_S)
        for t in clients:
            t.close()
    return {"ctrl_c_stop_s": round(took, 2), "exit_code": server.p.returncode, "tabs_still_computing": still}


def abandon_pool_task() -> dict:
    """Seconds from "newer settings" until a caller waiting on a minutes-long pool task is released."""
    from app.dashboard.pool import Pool, Superseded

    pool = Pool(1, timeout=4 * WAIT_S)
    stop: list = []
    try:
        g = pool.guarded(lambda: bool(stop))
        f = g.submit(time.sleep, 2 * WAIT_S)
        time.sleep(0.5)
        t0 = time.monotonic()
        stop.append(1)
        try:
            f.result(WAIT_S)
            released = float("nan")
        except Superseded:
            released = time.monotonic() - t0
    finally:
        pool.shutdown()
    return {"abandon_released_s": round(released, 3)}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=1, help="runs of each measurement (medians are printed)")
    ap.add_argument("--workers", type=int, default=2, help="the dashboard's process pool")
    ap.add_argument("--json", type=Path, help="write every run and the medians here")
    args = ap.parse_args(argv)
    runs = []
    for r in range(args.repeat):
        row = {**newer_settings_win(args.workers), **ctrl_c_during_work(args.workers), **abandon_pool_task()}
        print(f"run {r + 1}: {json.dumps(row)}", flush=True)
        runs.append(row)
    medians = {
        k: statistics.median(run[k] for run in runs)
        for k in runs[0]
        if isinstance(runs[0][k], float) and not isinstance(runs[0][k], bool)
    }
    out = {
        "runs": runs,
        "median": medians,
        "targets_s": {"light_after_*": 4.0, "ctrl_c_stop_s": 2.0, "abandon_released_s": 1.0},
    }
    print(json.dumps({"median": medians, "targets_s": out["targets_s"]}, indent=1))
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
