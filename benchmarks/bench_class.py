"""A class on one server: N tabs changing the panel every 2-5 s, over websockets as a browser does.

Starts ``python -m app.dashboard`` (loopback, free port) and connects ``--tabs`` clients
(:mod:`_wsclient`, what a browser sends; default 30). Every tab starts on the default
settings; every second tab first switches to the saturated what-if (Boeing 747 from
x0 = 20*[1,1,0,0]). Then, for ``--duration`` seconds (default 600), each tab makes one
change, waits for its answer (the status line's next "ready" or "error"), looks at it
for 2-5 s and makes the next. The change is drawn from these kinds:

* ``word length``: the slider b (1..16);
* ``data``: the data seed;
* ``Q/R``: one log10 weight slider of Q or R;
* ``saturated`` (Boeing tabs only): the input bound between 1 and 0.3 / 0.2.

Printed: p50/p95/max change -> answer per kind (seconds, as the tab saw it: the
status line arriving), the most often a tab said "queued behind N tabs" and the
largest N, whether every tab reached the final view of its last change ("ready",
and for a word length the b it asked for), tabs that died (closed, no answer
within ``--hang`` s), and memory (RSS of the server plus its workers) every
``--every`` seconds, with ``os.getloadavg()`` (other programs share the machine).

Example: ``python benchmarks/bench_class.py --tabs 30 --duration 600``
(short run: ``--tabs 8 --duration 60``).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import statistics
import sys
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _wsclient import WsTab, family_rss
from bench_soak import Server

KINDS = ("word length", "data", "Q/R", "saturated")
SATURATED_SETUP = (("system", "boeing747"), ("x0", "20, 20, 0, 0"))


class Student:
    """One tab: set up, then change something, wait for the answer, look 2-5 s, repeat until ``end``."""

    def __init__(self, url: str, index: int, hang: float, seed: int):
        self.index, self.hang = index, hang
        self.saturated = index % 2 == 1
        self.rnd = random.Random(seed)
        self.times: dict[str, list[float]] = {k: [] for k in KINDS}
        self.errors: list[str] = []
        self.queued_max, self.queued_seen = 0, 0
        self.last: tuple[str, object] | None = None
        self.final_ok, self.died, self.why = False, False, ""
        self.tab = WsTab(url, timeout=hang)
        self.b, self.seed, self.bound = 4, 0, 1.0
        self.pending: tuple | None = None  # the change waiting for its answer

    def change(self, label: str, value, kind: str | None) -> None:
        with self.tab._lock:
            start = len(self.tab.statuses)
        t0 = time.monotonic()
        self.pending = (label, value)
        self.tab.send(label, value)
        t1, text = self.tab.answer_after(start, self.hang)
        self.pending = None
        with self.tab._lock:
            seen = [s for _, s in self.tab.statuses[start:]]
        waits = [int(s.split()[2]) for s in seen if s.startswith("queued behind")]
        if waits:
            self.queued_seen += 1
            self.queued_max = max(self.queued_max, max(waits))
        if text.startswith("error"):
            self.errors.append(f"{label}={value!r}")
        if kind is not None:
            self.times[kind].append(t1 - t0)
            self.last = (label, value)

    def pick(self) -> tuple[str, str, object]:
        kinds = KINDS if self.saturated else KINDS[:3]
        kind = self.rnd.choice(kinds)
        if kind == "word length":
            self.b = self.rnd.choice([x for x in range(1, 17) if x != self.b])
            return kind, "word length b", self.b
        if kind == "data":
            self.seed += 1 + self.rnd.randint(0, 5)
            return kind, "data seed", self.seed
        if kind == "Q/R":
            sliders = [x for x in self.tab.labels("Q ") + self.tab.labels("R ") if "diagonal" not in x]  # no folder
            label = self.rnd.choice(sliders)
            value, now = round(self.rnd.uniform(-1.5, 1.5), 2), self.tab.value(label)
            while now is not None and abs(value - float(now)) < 1e-9:  # viser ignores a send of the same value
                value = round(self.rnd.uniform(-1.5, 1.5), 2)
            return kind, label, value
        now = self.tab.value("input bound")
        self.bound = self.rnd.choice([x for x in (1.0, 0.3, 0.2) if x != (self.bound if now is None else now)])
        return kind, "input bound", self.bound

    def run(self, end: float) -> None:
        try:
            self.tab.wait_ready(self.hang)
            if self.saturated:
                for label, value in SATURATED_SETUP:
                    self.change(label, value, None)
            while time.monotonic() < end:
                kind, label, value = self.pick()
                self.change(label, value, kind)
                time.sleep(self.rnd.uniform(2.0, 5.0))
            status = self.tab.status
            self.final_ok = status.startswith("ready") and (
                self.last is None or self.last[0] != "word length b" or f"b = {self.last[1]} " in status
            )
            if not self.final_ok:
                self.why = status
        except Exception as exc:  # no answer within the hang guard, or the connection closed
            self.died, self.why = True, f"waiting after {self.pending}: {type(exc).__name__}: {exc}"


def pct(xs: list[float], q: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(q * (len(xs) - 1))))] if xs else float("nan")


def _main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tabs", type=int, default=30)
    ap.add_argument("--duration", type=float, default=600.0, help="seconds of changes (default 600)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--every", type=float, default=30.0, help="seconds between memory samples")
    ap.add_argument("--hang", type=float, default=300.0, help="seconds without an answer that count as a dead tab")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--server-args", default="", help="extra options of qsid-dashboard")
    ap.add_argument("--json", type=Path, help="write the summary and samples here")
    ap.add_argument("--server-log", type=Path, help="write the server's stderr (its log, tracebacks included) here")
    a = ap.parse_args(argv)
    print(f"machine: {os.cpu_count()} cores; load average before the start {os.getloadavg()}", flush=True)
    server = Server("--workers", str(a.workers), *a.server_args.split())
    out: dict = {"tabs": a.tabs, "duration_s": a.duration, "cores": os.cpu_count()}
    samples: list = []
    students: list[Student] = []
    try:
        students = [Student(server.url, i, a.hang, a.seed + i) for i in range(a.tabs)]
        t0 = time.monotonic()
        end = t0 + a.duration
        threads = [threading.Thread(target=s.run, args=(end,), daemon=True) for s in students]
        for th in threads:
            th.start()
        while any(th.is_alive() for th in threads):
            srv, workers = family_rss(server.pid)
            row = {
                "t": round(time.monotonic() - t0),
                "server_mb": round(srv),
                "workers_mb": round(workers),
                "total_mb": round(srv + workers),
                "load": [round(x, 2) for x in os.getloadavg()],
                "changes": sum(len(v) for s in students for v in s.times.values()),
            }
            samples.append(row)
            print(
                f"{row['t']:6d} s  server {row['server_mb']:5d} MB + workers {row['workers_mb']:5d} MB = "
                f"{row['total_mb']:5d} MB  load {row['load']}  changes answered {row['changes']}",
                flush=True,
            )
            for th in threads:
                th.join(timeout=max(0.1, a.every / len(threads)))
        out.update(report(students, samples))
    finally:
        for s in students:
            s.tab.close()
        out["stop_s"] = round(server.stop(), 2)
        out["server_tracebacks"] = sum("Traceback" in line for line in server.errors)
        if out["server_tracebacks"]:
            out["server_stderr_tail"] = "".join(server.errors)[-6000:]
        if a.server_log:
            a.server_log.write_text("".join(server.errors), encoding="utf-8")
    print(json.dumps({k: v for k, v in out.items() if k != "samples"}, indent=1))
    if a.json:
        a.json.write_text(json.dumps(dict(out, samples=samples), indent=1))
    return out


def report(students: list[Student], samples: list) -> dict:
    out: dict = {"per_kind": {}}
    print(f"\n{'change':<12} {'n':>5} {'p50 s':>7} {'p95 s':>7} {'max s':>7}")
    for k in KINDS:
        xs = [x for s in students for x in s.times[k]]
        if xs:
            row = {"n": len(xs), "p50": pct(xs, 0.5), "p95": pct(xs, 0.95), "max": max(xs)}
            out["per_kind"][k] = {kk: round(v, 3) for kk, v in row.items()}
            print(f"{k:<12} {len(xs):5d} {row['p50']:7.2f} {row['p95']:7.2f} {row['max']:7.2f}")
    allx = [x for s in students for v in s.times.values() for x in v]
    out["all"] = {"n": len(allx), "p50": round(pct(allx, 0.5), 3), "p95": round(pct(allx, 0.95), 3)}
    out["tabs_final_view"] = sum(s.final_ok for s in students)
    out["tabs_died"] = [s.index for s in students if s.died]
    out["not_final"] = {s.index: s.why[:240] for s in students if not s.final_ok}
    out["changes_answered_with_error"] = sum(len(s.errors) for s in students)
    out["changes_that_said_queued"] = sum(s.queued_seen for s in students)
    out["most_tabs_ahead"] = max((s.queued_max for s in students), default=0)
    totals = [r["total_mb"] for r in samples]
    if totals:
        out["memory_mb"] = {"first": totals[0], "max": max(totals), "last": totals[-1]}
        out["memory_median_first_half_mb"] = statistics.median(totals[: max(1, len(totals) // 2)])
        out["memory_median_second_half_mb"] = statistics.median(totals[len(totals) // 2 :])
    out["load_during"] = samples[-1]["load"] if samples else None
    print(
        f"\ntabs reaching the final view of their last change: {out['tabs_final_view']} / {len(students)}; "
        f"died: {out['tabs_died']}; changes that said 'queued behind N tabs': {out['changes_that_said_queued']} "
        f"(at most {out['most_tabs_ahead']} ahead)",
        flush=True,
    )
    return out


def main(argv=None) -> dict:
    """Run the benchmark; ``--save FILE`` also writes the printed output to FILE (header first)."""
    import _tee

    return _tee.run(_main, argv)


if __name__ == "__main__":
    main()
