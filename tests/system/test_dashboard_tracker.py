"""multiprocessing's resource tracker of a running dashboard killed: one line in the log (no ``KeyError: '/mp-…'``
tracebacks), no zombie, and the dashboard keeps working, also when its pool is replaced afterwards."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from support import HANG_S, descendants, gone_within, wait_until

# slow: starts a real dashboard process and kills its resource tracker
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


def _trackers(server: int, module: bytes) -> list[int]:
    return [p for p in descendants(server) if module in _cmdline(p)]


def test_a_killed_resource_tracker_is_replaced_quietly():
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
        wait_until(lambda: _trackers(p.pid, b"resource_tracker"), "the resource tracker runs")
        old = _trackers(p.pid, b"resource_tracker")[0]
        os.kill(old, signal.SIGKILL)
        wait_until(lambda: any(f"resource tracker (pid {old}) ended" in x for x in err), "the one line")
        assert not os.path.exists(f"/proc/{old}")  # reaped at once: no zombie
        assert _trackers(p.pid, b"app.tracker"), "no new tracker"
        tab = WsTab(line.split()[2], timeout=HANG_S)
        tab.wait_ready(HANG_S)
        workers = [x for x in descendants(p.pid) if b"spawn_main" in _cmdline(x)]
        os.kill(workers[0], signal.SIGKILL)  # the pool is replaced: the old pool's semaphores are released
        for b in (6, 7):  # the first change may be the one that finds the pool broken (then it is retried)
            with tab._lock:
                start = len(tab.statuses)
            tab.send("word length b", b)
            _, text = tab.answer_after(start, HANG_S)
            assert text.startswith("ready") and f"b = {b} " in text, text
        desc = descendants(p.pid)
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
    assert "Traceback" not in log and "KeyError" not in log, log[-3000:]
    assert sum("resource tracker" in x for x in err) == 1, log[-3000:]
