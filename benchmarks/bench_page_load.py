"""First page load of the dashboard in headless Chromium: page open -> "ready" (issue 9 target <= 3 s).

Starts ``python -m app.dashboard`` (its own process, 127.0.0.1, a free port) and
opens it in Debian's ``/usr/bin/chromium`` through playwright, in a fresh browser
context per tab (no HTTP cache). For each server start it times

* the **first tab** after the server started (cold: no cached results, pool workers
  loading the compiled kernels), and
* a **second tab** on the same server (what every later visitor sees),

from ``page.goto`` to: the first canvas, the first plotly plot drawn, and the
status line saying "ready" (every curve drawn). It also counts the websocket bytes
the tab received until "ready" (compressed by viser), the largest single message
(plotly.js travels as one), and when the first, the largest and the last message
arrived (seconds from page open). "server" is the tab's own "all
curves in ... s" (its computation, from its first settings to the last curve). Medians over ``--runs`` server starts; the machine's load is
printed, since on a shared 2-core machine all of this moves with it.

Usage::

    python benchmarks/bench_page_load.py              # 3 server starts, the dashboard's defaults
    python benchmarks/bench_page_load.py --workers 0  # server computing in-process
"""

from __future__ import annotations

import argparse
import os
import signal
import socket
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT / "benchmarks") not in sys.path:
    sys.path.insert(0, str(ROOT / "benchmarks"))
from _support import DashboardProcess, stop_tree  # noqa: E402

CHROMIUM = "/usr/bin/chromium"
ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
    "--disable-quic",
    "--disable-sync",
]
TARGET_S = 3.0
TIMEOUT_MS = 120_000


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_server(workers: int, system: str) -> tuple[subprocess.Popen, str, float]:
    """``python -m app.dashboard`` on a free port; returns (process, url, seconds until it printed its URL)."""
    port = _free_port()
    srv = DashboardProcess("--workers", str(workers), "--system", system, port=port)
    return srv.p, f"http://127.0.0.1:{port}", srv.started_s


def stop_server(proc: subprocess.Popen) -> int:
    """SIGTERM the server (its graceful stop); returns how many of its processes outlived it by 30 s (killed)."""
    return stop_tree(proc, signal.SIGTERM, 30.0)[1]


def open_tab(browser, url: str) -> dict:
    """One fresh tab: seconds to the first canvas, the first plot, "ready"; websocket bytes until "ready".

    Websocket arrival times are taken when playwright reports the frame; this script
    is always inside a playwright call (goto, wait_for_*) meanwhile, so reports come at once.
    """
    ctx = browser.new_context(viewport={"width": 1400, "height": 900})
    page = ctx.new_page()
    log: list = []
    page.on("websocket", lambda ws: ws.on("framereceived", lambda p: log.append((time.perf_counter() - t0, len(p)))))
    t0 = time.perf_counter()
    page.goto(url, timeout=TIMEOUT_MS)
    out = {"html": time.perf_counter() - t0}
    page.wait_for_selector("canvas", timeout=TIMEOUT_MS)
    out["canvas"] = time.perf_counter() - t0
    page.wait_for_function(
        "document.querySelectorAll('.js-plotly-plot .main-svg').length >= 1", timeout=TIMEOUT_MS, polling=50
    )
    out["first plot"] = time.perf_counter() - t0
    page.wait_for_function("document.body.innerText.includes('ready ·')", timeout=TIMEOUT_MS, polling=50)
    out["ready"] = time.perf_counter() - t0
    sizes = [n for _, n in log]
    out["MB"] = sum(sizes) / 2**20
    out["largest MB"] = max(sizes, default=0) / 2**20
    out["messages"] = len(sizes)
    if log:
        out["first ws msg"] = log[0][0]
        out["plotly.js msg"] = max(log, key=lambda x: x[1])[0]
        out["last ws msg"] = log[-1][0]
    out["plots"] = page.evaluate("document.querySelectorAll('.js-plotly-plot').length")
    out["server"] = page.evaluate("""() => { const m = document.body.innerText.match(
        /drawn in ([0-9.]+) s, all curves in ([0-9.]+) s/); return m ? parseFloat(m[2]) : null; }""")
    ctx.close()
    return out


def _fmt(runs: list, key: str, unit: str = "s") -> str:
    xs = [r[key] for r in runs if r.get(key) is not None]
    if not xs:
        return f"{key} -"
    return f"{key} {statistics.median(xs):.2f} {unit} ({min(xs):.2f}-{max(xs):.2f})"


def _main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=3, help="server starts (each: a first and a second tab)")
    p.add_argument("--workers", type=int, default=2, help="the server's --workers")
    p.add_argument("--system", default="dc-motor")
    a = p.parse_args(argv)
    if not Path(CHROMIUM).exists():
        print(f"{CHROMIUM} is missing: nothing measured")
        return 1
    from playwright.sync_api import sync_playwright

    first, second, starts, orphans = [], [], [], 0
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
        for _ in range(a.runs):
            proc, url, t_start = start_server(a.workers, a.system)
            starts.append(t_start)
            try:
                first.append(open_tab(browser, url))
                second.append(open_tab(browser, url))
            finally:
                orphans += stop_server(proc)
        browser.close()
    print(
        f"qsid dashboard first page load · headless Chromium (software WebGL) · {a.system} · server --workers "
        f"{a.workers} · {a.runs} server starts · {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}"
    )
    print(f"server start to URL: median {statistics.median(starts):.2f} s")
    print(f"server processes left running after SIGTERM (killed by this script): {orphans}")
    for name, runs in (("first tab after start", first), ("second tab", second)):
        ready = statistics.median(r["ready"] for r in runs)
        verdict = "MET" if ready <= TARGET_S else "NOT MET"
        print(
            f"{name}: page open -> ready median {ready:.2f} s (target <= {TARGET_S:.0f} s: {verdict}) · "
            + " · ".join(
                _fmt(runs, k)
                for k in (
                    "html",
                    "canvas",
                    "first ws msg",
                    "plotly.js msg",
                    "first plot",
                    "last ws msg",
                    "ready",
                    "server",
                )
            )
            + f" · websocket {_fmt(runs, 'MB', 'MB')}, {_fmt(runs, 'largest MB', 'MB')}, "
            f"{statistics.median(r['messages'] for r in runs):.0f} messages · "
            f"{statistics.median(r['plots'] for r in runs):.0f} plotly plots"
        )
    return 0


def main(argv=None) -> int:
    """Run the benchmark; ``--save FILE`` also writes the printed output to FILE (header first)."""
    import _tee

    return _tee.run(_main, argv)


if __name__ == "__main__":
    sys.exit(main())
