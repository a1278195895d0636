"""Soak and flood of a real dashboard server: its memory (RSS) over time, and a new tab's wait during a flood.

Starts ``python -m app.dashboard`` on a free loopback port and drives it with
plain websocket clients (:mod:`_wsclient`, what a browser sends):

1. ``--storm-clients`` clients (default 10) at ``--storm-rate`` changes/s each for ``--storm-seconds``;
2. the soak: ``--clients`` clients (default 3) at ``--rate`` changes/s each for ``--minutes`` (default 10);
3. all clients close; RSS is read again over ``--settle`` seconds (default 45: a server with no tab
   left gives its results and the workers' data back after 20 s, :mod:`app.dashboard.lifecycle`);
4. optionally (``--flood SECONDS``) ``--flood-clients`` clients (default 5, in a process of their own)
   send changes as fast as they can while a new tab connects: seconds until it says "ready", the
   flood's rate, and whether the flooding clients stayed connected.

Prints one line per sample (``t``, phase, RSS of the server and of its pool workers) and a JSON
summary (``--json FILE`` writes it with every sample; ``--save FILE`` writes the printed output).
Example: ``python benchmarks/bench_soak.py --minutes 3 --flood 20``.
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from _support import DashboardProcess, family_rss, rss_mb
from _wsclient import WsTab

#: What the clients change: panel label -> a random value in the panel's own range.
CHANGES = (
    ("word length b", lambda r: r.randint(1, 16)),
    ("realizations", lambda r: r.randint(1, 30)),
    ("closed-loop steps", lambda r: 5 * r.randint(1, 20)),
    ("input bound", lambda r: r.choice([0.5, 1.0, 2.0])),
    ("data seed", lambda r: r.randint(0, 50)),
)


class Server(DashboardProcess):
    """``python -m app.dashboard --port 0`` (loopback) with extra options; ``url``, ``pid``, ``rss``, ``stop()``."""

    def __init__(self, *args: str):
        super().__init__(*args, timeout=120)

    @property
    def rss(self) -> float:
        return rss_mb(self.pid)


class Clients:
    """``n`` tabs changing random inputs at ``rate`` changes/s each (``rate <= 0``: as fast as they can)."""

    def __init__(self, url: str, n: int, rate: float, seed: int = 0, timeout: float = 60.0):
        self.url, self.rate, self.sent, self.failed, self.timeout = url, rate, 0, 0, timeout
        self._stop = threading.Event()
        self.tabs = [WsTab(url, timeout) for _ in range(n)]
        self.threads = [
            threading.Thread(target=self._run, args=(t, seed + i), daemon=True) for i, t in enumerate(self.tabs)
        ]
        for th in self.threads:
            th.start()

    def _run(self, tab: WsTab, seed: int) -> None:
        rnd = random.Random(seed)
        try:
            tab.wait_for("closed-loop steps", self.timeout)
            while not self._stop.is_set():
                label, value = rnd.choice(CHANGES)
                tab.send(label, value(rnd))
                self.sent += 1
                if self.rate > 0:
                    time.sleep(1.0 / self.rate)
        except Exception:
            self.failed += 1

    @property
    def connected(self) -> int:
        return sum(not t.closed for t in self.tabs)

    def close(self) -> None:
        self._stop.set()
        for th in self.threads:
            th.join(10)
        for t in self.tabs:
            t.close()


def phase(server: Server, name: str, seconds: float, every: float, t0: float, samples: list, clients=None) -> None:
    end = time.monotonic() + seconds
    while True:
        now = time.monotonic()
        srv, workers = family_rss(server.pid)
        row = {"t": round(now - t0, 1), "phase": name, "rss_mb": round(srv, 1), "workers_mb": round(workers, 1)}
        if clients is not None:
            row["sent"] = clients.sent
        samples.append(row)
        print(
            f"{row['t']:8.1f} s  {name:8s} RSS server {row['rss_mb']:7.1f} MB + workers {row['workers_mb']:6.1f} MB"
            + (f"  changes sent {clients.sent}" if clients is not None else ""),
            flush=True,
        )
        if now >= end:
            return
        time.sleep(min(every, max(0.0, end - now)))


def _flood_process(url: str, clients: int, seconds: float, out) -> None:
    """In a process of its own (its threads do not slow the measuring tab down): flood, then report."""
    c = Clients(url, clients, rate=0, seed=1000)
    try:
        t0 = time.monotonic()
        time.sleep(seconds)
        out.put({"sent": c.sent, "seconds": time.monotonic() - t0, "connected": c.connected, "failed": c.failed})
    finally:
        c.close()


def flood(url: str, clients: int, seconds: float, settle: float = 2.0) -> dict:
    """``clients`` tabs (in a separate process) send changes as fast as they can for ``seconds``; a new tab
    connects ``settle`` s in: seconds until it says "ready", the flood's rate, and who stayed connected."""
    import multiprocessing

    ctx = multiprocessing.get_context("spawn")
    out = ctx.Queue()
    proc = ctx.Process(target=_flood_process, args=(url, clients, seconds, out), daemon=True)
    proc.start()
    try:
        time.sleep(settle)
        tab = WsTab(url)
        try:
            ready = tab.wait_ready(max(5.0, seconds - settle))
        except (TimeoutError, ConnectionError):
            ready = float("nan")
        finally:
            tab.close()
        r = out.get(timeout=seconds + 60)
    finally:
        proc.join(30)
        if proc.is_alive():
            proc.kill()
    return {
        "new_tab_ready_s": round(ready, 2),
        "flood_changes_per_s": round(r["sent"] / r["seconds"]),
        "flooders_still_connected": r["connected"],
        "flooders": clients,
    }


def main(argv=None) -> dict:
    """Run it; ``--save FILE`` also writes the printed output to FILE (header first)."""
    import _tee

    argv = list(sys.argv[1:] if argv is None else argv)
    path = _tee.pop_save(argv)
    with _tee.saved(path, argv):
        return _main(argv)


def _main(argv) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0, help="soak length (default 10)")
    ap.add_argument("--clients", type=int, default=3)
    ap.add_argument("--rate", type=float, default=10.0, help="changes per second per soak client")
    ap.add_argument("--storm-clients", type=int, default=10)
    ap.add_argument("--storm-rate", type=float, default=30.0)
    ap.add_argument("--storm-seconds", type=float, default=60.0)
    ap.add_argument(
        "--settle", type=float, default=45.0, help="seconds after the clients closed (the server releases after 20)"
    )
    ap.add_argument("--every", type=float, default=30.0, help="seconds between RSS samples in the soak")
    ap.add_argument("--flood", type=float, default=0.0, metavar="SECONDS", help="also flood (0: no)")
    ap.add_argument("--flood-clients", type=int, default=5, help="clients sending as fast as they can")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--server-args", default="", help="extra options of qsid-dashboard, e.g. '--cache-mb 128'")
    ap.add_argument("--json", type=Path, help="write the samples and summary here")
    args = ap.parse_args(argv)
    server = Server("--workers", str(args.workers), *args.server_args.split())
    samples: list = []
    t0 = time.monotonic()
    srv, workers = family_rss(server.pid)
    out: dict = {"start_rss_mb": round(srv, 1), "start_workers_mb": round(workers, 1)}
    try:
        if args.storm_seconds > 0 and args.storm_clients > 0:
            c = Clients(server.url, args.storm_clients, args.storm_rate)
            phase(server, "storm", args.storm_seconds, 10.0, t0, samples, c)
            c.close()
            out["storm_changes"] = c.sent
        c = Clients(server.url, args.clients, args.rate, seed=100)
        phase(server, "soak", args.minutes * 60.0, args.every, t0, samples, c)
        c.close()
        out["soak_changes"] = c.sent
        phase(server, "closed", args.settle, args.settle / 2, t0, samples)
        if args.flood > 0:
            out["flood"] = flood(server.url, args.flood_clients, args.flood)
            print(f"flood: {out['flood']}", flush=True)
        soak = [s["rss_mb"] for s in samples if s["phase"] == "soak"]
        closed = [s for s in samples if s["phase"] == "closed"]
        out.update(
            samples=samples,
            closed_rss_mb=closed[0]["rss_mb"],
            closed_workers_mb=closed[0]["workers_mb"],
            end_rss_mb=closed[-1]["rss_mb"],
            end_workers_mb=closed[-1]["workers_mb"],
            peak_rss_mb=max(s["rss_mb"] for s in samples),
            soak_first_mb=soak[0],
            soak_last_mb=soak[-1],
        )
    finally:
        out["stop_seconds"] = round(server.stop(), 2)
        out["server_tracebacks"] = sum("Traceback" in line for line in server.errors)
        if out["server_tracebacks"]:
            out["server_stderr_tail"] = "".join(server.errors)[-4000:]
    print(json.dumps({k: v for k, v in out.items() if k != "samples"}, indent=1))
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
