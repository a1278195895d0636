"""A running dashboard's processes: its pool workers and loky's resource trackers, nothing else; a killed worker is
replaced and the tab keeps working; the stop leaves nothing and logs no traceback nor a leak warning."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from support import HANG_S, descendants, gone_within, pool_workers, wait_until

# slow: starts a real dashboard process and kills one of its workers
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _wsclient import WsTab  # noqa: E402


def _cmdline(pid: int) -> bytes:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return f.read()
    except OSError:
        return b""


def test_only_pool_workers_and_a_killed_one_is_replaced():
    p = subprocess.Popen(
        [sys.executable, "-m", "app.dashboard", "--port", "0", "--workers", "2"],
        cwd=ROOT,
        env=dict(os.environ, PYTHONPATH=str(ROOT)),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    err: list[str] = []
    reader = threading.Thread(target=lambda: err.extend(p.stderr), daemon=True)
    reader.start()
    tab, desc = None, []
    try:
        line, end = "", time.monotonic() + HANG_S
        while not line.startswith("qsid dashboard: http") and time.monotonic() < end and p.poll() is None:
            line = p.stdout.readline()
        assert line.startswith("qsid dashboard: http"), "".join(err)
        threading.Thread(target=p.stdout.read, daemon=True).start()
        tab = WsTab(line.split()[2], timeout=HANG_S)
        tab.wait_ready(HANG_S)
        kids = descendants(p.pid)
        workers = pool_workers(p.pid)
        others = [x for x in kids if x not in workers]
        assert len(workers) == 2 and all(b"resource_tracker" in _cmdline(x) for x in others), [
            _cmdline(x)[:80] for x in kids
        ]
        os.kill(workers[0], signal.SIGKILL)  # its pool is broken: the other worker is ended too
        wait_until(lambda: not set(descendants(p.pid)) & set(workers), "the old workers ended and reaped")
        for seed in (11, 12):  # new data: pool work; the first change finds the pool broken, replaces it, retries
            with tab._lock:
                start = len(tab.statuses)
            tab.send("data seed", seed)
            _, text = tab.answer_after(start, HANG_S)
            assert text.startswith("ready"), text
        assert len(pool_workers(p.pid)) == 2 and not set(pool_workers(p.pid)) & set(workers)
        desc = descendants(p.pid)  # the new workers and the trackers: all must end with the server
    except BaseException:
        print("the dashboard's stderr:\n" + "".join(err))  # shown with the failure
        raise
    finally:
        if tab is not None:
            tab.close()
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
            try:
                p.wait(HANG_S)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(10)
    left = gone_within(desc, 60)
    for x in left:
        os.kill(x, signal.SIGKILL)
    reader.join(60)
    log = "".join(err)
    assert left == [] and p.returncode == 0, (left, p.returncode, log[-3000:])
    assert "Traceback" not in log and "KeyError" not in log and "leaked" not in log, log[-3000:]
