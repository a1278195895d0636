"""app.procs.process_pool (loky): results and errors; a killed worker fails its pool's tasks and nothing hangs; a
kill stops busy and stopped workers and reaps them; workers end when their program is killed outright."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

import pytest
from support import HANG_S, alive, descendants, gone_within, pool_workers, wait_until

from app.procs import process_pool

# slow: starts real worker processes
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]


def _boom() -> None:
    raise KeyError("a task's own error")


def _sigint_ignored() -> bool:
    return signal.getsignal(signal.SIGINT) is signal.SIG_IGN


def test_results_errors_and_workers_started_at_once():
    before = set(pool_workers(os.getpid()))
    pool = process_pool(2)
    try:
        workers = set(pool_workers(os.getpid())) - before
        assert len(workers) == 2  # started before the pool is returned
        assert [f.result(HANG_S) for f in [pool.submit(math.sqrt, x) for x in (0, 1, 4, 9)]] == [0, 1, 2, 3]
        assert list(pool.map(abs, [-1, -2])) == [1, 2]
        with pytest.raises(KeyError, match="a task's own error"):
            pool.submit(_boom).result(HANG_S)
        assert pool.submit(_sigint_ignored).result(HANG_S)  # Ctrl-C belongs to the program
    finally:
        pool.shutdown()
    assert gone_within(sorted(workers), 60) == []


def test_a_killed_worker_fails_the_pool_and_nothing_hangs():
    before = set(pool_workers(os.getpid()))
    pool = process_pool(2)
    try:
        busy = pool.submit(time.sleep, 30)
        wait_until(lambda: busy.running(), "the task runs")
        workers = sorted(set(pool_workers(os.getpid())) - before)
        os.kill(workers[0], signal.SIGKILL)
        with pytest.raises(BrokenProcessPool):
            busy.result(HANG_S)
        with pytest.raises(BrokenProcessPool):
            pool.submit(abs, 1).result(HANG_S)
    finally:
        pool.shutdown(kill_workers=True)
    assert gone_within(workers, 60) == []


def test_kill_stops_busy_and_stopped_workers_and_reaps_them():
    before = set(pool_workers(os.getpid()))
    pool = process_pool(2)
    workers = sorted(set(pool_workers(os.getpid())) - before)
    busy = [pool.submit(time.sleep, 60) for _ in range(2)]
    wait_until(lambda: all(f.running() for f in busy), "both tasks run")
    os.kill(workers[0], signal.SIGSTOP)  # a stopped worker never finishes its task
    t0 = time.monotonic()
    pool.shutdown(kill_workers=True)
    print(f"killed and reaped in {time.monotonic() - t0:.3f} s")
    assert not any(alive(w) for w in workers)  # reaped: not even a zombie
    assert all(f.done() for f in busy)


def test_workers_end_when_their_program_is_killed_outright():
    code = textwrap.dedent(
        """
        import os, time
        from app.procs import process_pool
        pool = process_pool(2)
        pool.submit(time.sleep, 600)  # one busy worker, one idle
        print("ready", flush=True)
        time.sleep(600)
        """
    )
    p = subprocess.Popen(
        [sys.executable, "-c", code], cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)), stdout=subprocess.PIPE
    )
    try:
        assert p.stdout is not None and p.stdout.readline().strip() == b"ready"
        tree = descendants(p.pid)
        workers = pool_workers(p.pid)
        assert len(workers) == 2, tree
        p.kill()  # SIGKILL: no handler of the program runs
        p.wait(HANG_S)
        left = gone_within(tree, 60)  # the workers, and loky's resource trackers once they are gone
    finally:
        if p.poll() is None:
            p.kill()
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    assert left == []
