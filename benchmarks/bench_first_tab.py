"""First tab of a new server with an empty numba cache against a warm one (the server warms before 'ready').

Starts ``python -m app.dashboard`` with ``NUMBA_CACHE_DIR`` pointed at a new temporary directory (empty
cache: everything compiles), then again on the same directory (warm cache); for each, seconds from
start to the printed URL and from opening one websocket tab to its "ready". Prints the ratio of the
first tab's time empty/warm (target <= 1.3: the compile is paid before the URL, not by the tab).
Every server is stopped with SIGTERM and its processes checked (leftovers are killed and counted).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _support import DashboardProcess
from _wsclient import WsTab
from bench_page_load import stop_server


def one(cache: str) -> tuple[float, float, int]:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=str(ROOT))
    srv = DashboardProcess("--workers", "2", env=env)
    p, url, start = srv.p, srv.url, srv.started_s
    try:
        tab = WsTab(url)
        try:
            ready = tab.wait_ready(300)
        finally:
            tab.close()
    finally:
        left = stop_server(p)
    return start, ready, left


def _main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=2)
    a = ap.parse_args(argv)
    cold, warm, left = [], [], 0
    for _ in range(a.runs):
        with tempfile.TemporaryDirectory(prefix="qsid-numba-") as d:
            for out in (cold, warm):
                s, r, n = one(d)
                out.append((s, r))
                left += n
    med = lambda xs, i: statistics.median(x[i] for x in xs)  # noqa: E731
    print(f"first tab, new server, {a.runs} run(s), {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}")
    print(f"empty numba cache: start -> URL {med(cold, 0):.2f} s, tab open -> ready {med(cold, 1):.2f} s")
    print(f"warm numba cache:  start -> URL {med(warm, 0):.2f} s, tab open -> ready {med(warm, 1):.2f} s")
    print(
        f"first tab empty/warm ratio {med(cold, 1) / med(warm, 1):.2f} (target <= 1.3); "
        f"server processes left after SIGTERM: {left}"
    )


def main(argv=None) -> None:
    """Run the benchmark; ``--save FILE`` also writes the printed output to FILE (header first)."""
    import _tee

    return _tee.run(_main, argv)


if __name__ == "__main__":
    main()
