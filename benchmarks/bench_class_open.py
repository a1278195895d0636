"""A class opening the same link at once, against one tab alone: first view, "ready" and b changes.

Two fresh servers (``python -m app.dashboard --workers 2``, loopback, free port), in one run:

* alone: one tab opens; seconds to its first view (the current b drawn: the status moves past
  "(1/16)") and to "ready"; then ``--changes`` changes of the word length b, each timed to its answer;
* class: ``--tabs`` tabs (default 30) open ``--gap`` s apart (default 0.2 s), all on the default
  settings; seconds from each tab's opening to its first view and to "ready"; then every tab makes
  ``--changes`` changes of b (the same b's as the lone tab, in its own order), each timed to its answer.

Printed: the lone tab's figures; the class's median, p95 and max; and the ratios the service targets
(the last tab's first view over the lone tab's first view, target <= 3; the p95 of a b change in the
class over the lone tab's, target <= 5). Every server is stopped with SIGTERM and its processes checked.

Example: ``python benchmarks/bench_class_open.py`` (short: ``--tabs 8 --changes 2``).
"""

from __future__ import annotations

import argparse
import os
import random
import statistics
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _support import DashboardProcess
from _wsclient import WsTab
from bench_page_load import stop_server

B_LABEL = "word length b"
BITS = (9, 6, 11, 3, 7)  # none is the default b (4): viser ignores a send of the value it holds


def seen(tab: WsTab, t0: float, timeout: float, first: bool) -> float:
    """Seconds from ``t0`` (monotonic) until the tab shows its current b (``first``: a status past "(1/16)") or
    says "ready" (an error counts as an answer too)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        for at, text in list(tab.statuses):
            if text.startswith(("ready", "error")) or (first and text.startswith("computing") and "(1/" not in text):
                return at - t0
        if tab.closed:
            raise ConnectionError(f"the connection ended ({tab.close_reason})")
        time.sleep(0.01)
    raise TimeoutError(f"no {'first view' if first else 'ready'} within {timeout} s (status: {tab.status!r})")


def change_b(tab: WsTab, b: int, timeout: float) -> float:
    """Set b and wait for the answer ("ready" for that b, or an error); seconds."""
    index, t0 = len(tab.statuses), time.monotonic()
    tab.send(B_LABEL, b)
    while True:
        at, text = tab.answer_after(index, timeout - (time.monotonic() - t0))
        if text.startswith("error") or f"b = {b} " in text:
            return at - t0
        index = next(i for i, s in enumerate(tab.statuses) if s[0] == at) + 1


def open_tabs(url: str, n: int, gap: float, timeout: float) -> tuple[list[WsTab], list[float], list[float]]:
    """``n`` tabs opened ``gap`` s apart; each one's seconds to its first view and to "ready"."""
    tabs: list[WsTab] = []
    starts: list[float] = []
    for _ in range(n):
        starts.append(time.monotonic())
        tabs.append(WsTab(url, timeout=timeout))
        time.sleep(gap)
    views = [seen(t, s, timeout, True) for t, s in zip(tabs, starts, strict=True)]
    readies = [seen(t, s, timeout, False) for t, s in zip(tabs, starts, strict=True)]
    return tabs, views, readies


def class_changes(tabs: list[WsTab], changes: int, timeout: float) -> list[float]:
    """Every tab changes b ``changes`` times (its own order of :data:`BITS`), all tabs at once; every answer's seconds."""
    out: list[float] = []
    lock = threading.Lock()

    def student(i: int, tab: WsTab) -> None:
        bits = list(BITS[:changes])
        random.Random(i).shuffle(bits)
        time.sleep(random.Random(i).uniform(0, 1))
        for b in bits:
            s = change_b(tab, b, timeout)
            with lock:
                out.append(s)

    threads = [threading.Thread(target=student, args=(i, t)) for i, t in enumerate(tabs)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout * changes + 10)
    return out


def p95(xs: list[float]) -> float:
    return sorted(xs)[max(0, int(round(0.95 * len(xs))) - 1)]


def run(tabs_n: int, gap: float, changes: int, timeout: float) -> dict[str, float]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    srv = DashboardProcess("--workers", "2", env=env)
    try:
        tabs, views, readies = open_tabs(srv.url, 1, 0.0, timeout)
        alone_changes = [change_b(tabs[0], b, timeout) for b in BITS[:changes]]
        tabs[0].close()
    finally:
        left = stop_server(srv.p)
    print(f"one tab alone: first view {views[0]:.2f} s, ready {readies[0]:.2f} s; b changes {_fmt(alone_changes)}")
    srv = DashboardProcess("--workers", "2", env=env)
    try:
        tabs, views_c, readies_c = open_tabs(srv.url, tabs_n, gap, timeout)
        changes_c = class_changes(tabs, changes, timeout)
        for t in tabs:
            t.close()
    finally:
        left += stop_server(srv.p)
    print(
        f"{tabs_n} tabs opened {gap} s apart: first view median {statistics.median(views_c):.2f} s, "
        f"max {max(views_c):.2f} s (last tab {views_c[-1]:.2f} s); ready median {statistics.median(readies_c):.2f} s, "
        f"max {max(readies_c):.2f} s"
    )
    print(f"{tabs_n} tabs changing b: {len(changes_c)} answers, {_fmt(changes_c)}")
    worst_view = max(views_c)
    out = {
        "last tab first view / alone": worst_view / views[0],
        "p95 b change class / alone": p95(changes_c) / p95(alone_changes),
    }
    print(f"slowest tab's first view / one tab's alone: {out['last tab first view / alone']:.2f} (target <= 3)")
    print(f"p95 of a b change, class / alone: {out['p95 b change class / alone']:.2f} (target <= 5)")
    print(f"processes left after the servers stopped (killed): {left}; load average {os.getloadavg()[0]:.2f}")
    return out


def _fmt(xs: list[float]) -> str:
    return f"median {statistics.median(xs):.2f} s, p95 {p95(xs):.2f} s, max {max(xs):.2f} s"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tabs", type=int, default=30)
    ap.add_argument("--gap", type=float, default=0.2)
    ap.add_argument("--changes", type=int, default=3, choices=range(1, len(BITS) + 1))
    ap.add_argument("--timeout", type=float, default=300.0)
    a = ap.parse_args()
    run(a.tabs, a.gap, a.changes, a.timeout)


if __name__ == "__main__":
    main()
