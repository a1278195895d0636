"""A running dashboard's processes: its pool workers only (no multiprocessing resource tracker: the pool uses no
semaphore); a killed worker is replaced and the tab keeps working; the stop leaves nothing and logs no traceback."""

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
        workers = [x for x in kids if b"from app.procs import serve" in _cmdline(x)]
        assert len(workers) == 2 and sorted(workers) == sorted(kids), [_cmdline(x)[:80] for x in kids]
        assert not any(b"resource_tracker" in _cmdline(x) for x in kids)
        os.kill(workers[0], signal.SIGKILL)  # the pool is replaced
        for b in (6, 7):  # the first change may be the one that finds the pool broken (then it is retried)
            with tab._lock:
                start = len(tab.statuses)
            tab.send("word length b", b)
            _, text = tab.answer_after(start, HANG_S)
            assert text.startswith("ready") and f"b = {b} " in text, text
        # the dead worker's pool is replaced at once (also while idle): two new workers, the old ones reaped
        wait_until(lambda: not set(descendants(p.pid)) & set(workers), "the old workers gone")
        desc = descendants(p.pid)
        assert len(desc) == 2 and all(b"from app.procs import serve" in _cmdline(x) for x in desc), desc
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
