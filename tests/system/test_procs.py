"""app.procs.ProcessPool: workers started with subprocess and fed over pipes; results, errors, a dead worker,
shutdown, and no multiprocessing resource tracker."""

from __future__ import annotations

import math
import os
import signal
import time
from concurrent.futures.process import BrokenProcessPool

import pytest
from support import HANG_S, descendants, wait_until

from app.procs import ProcessPool, kill_workers, resource_trackers, worker_pids

# slow: starts real worker processes
pytestmark = pytest.mark.slow


def _boom() -> None:
    raise KeyError("a task's own error")


def test_results_errors_and_each_worker():
    before = resource_trackers(os.getpid())  # earlier tests in this process (a dask cluster) may have one
    pool = ProcessPool(2)
    try:
        assert [f.result(HANG_S) for f in [pool.submit(math.sqrt, x) for x in (0, 1, 4, 9)]] == [0, 1, 2, 3]
        assert list(pool.map(abs, [-1, -2])) == [1, 2]
        with pytest.raises(KeyError, match="a task's own error"):
            pool.submit(_boom).result(HANG_S)
        assert sorted(pool.each(os.getpid, HANG_S)) == sorted(pool.pids()) == sorted(worker_pids(pool))
        assert set(pool.pids()) <= set(descendants(os.getpid()))
        assert resource_trackers(os.getpid()) <= before  # no semaphore anywhere: the pool starts no tracker
    finally:
        pool.shutdown()
    assert not set(pool.pids()) & set(descendants(os.getpid()))  # ended and reaped


def test_a_killed_worker_breaks_the_pool_and_nothing_hangs():
    pool = ProcessPool(2)
    try:
        busy = pool.submit(time.sleep, 30)
        wait_until(lambda: busy.running(), "the task runs")
        os.kill(pool.pids()[0], signal.SIGKILL)
        later = pool.submit(time.sleep, 30)
        for f in (busy, later):
            with pytest.raises(BrokenProcessPool):
                f.result(HANG_S)
        assert pool.broken
        with pytest.raises(BrokenProcessPool):
            pool.submit(abs, 1)
    finally:
        kill_workers(pool)
        pool.shutdown()
    wait_until(lambda: not set(pool.pids()) & set(descendants(os.getpid())), "the workers reaped")


def test_a_worker_dead_while_idle_breaks_the_pool_at_once():
    pool = ProcessPool(1)
    try:
        os.kill(pool.pids()[0], signal.SIGKILL)
        wait_until(lambda: pool.broken, "the pool notices")
    finally:
        pool.shutdown()
