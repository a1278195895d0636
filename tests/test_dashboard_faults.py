"""Faults of the shared process pool while several tabs compute: a worker killed, a worker frozen.

Each test runs a real server in-process (workers=2) with two tabs; the pool is
replaced exactly once per failed pool (never one another tab already replaced),
and every tab either draws its newest setting after one retry or says why.
"""

from __future__ import annotations

import os
import signal
import time

import pytest

from app.dashboard import DashboardApp
from app.dashboard.pool import Pool, PoolTimeout, Superseded
from test_dashboard_server import SMALL, app, open_tab  # noqa: F401  (the in-process app fixture)

HEAVIER = dict(trajectories=60, steps=400, realizations=40)


def _pids(app) -> list[int]:
    return [p.pid for p in app.executor._processes.values()]


@pytest.fixture
def pooled():
    a = DashboardApp(host="127.0.0.1", port=0, workers=2, task_timeout=3.0)
    yield a
    a.stop()


def _start_both(tabs, bits):
    for t, b in zip(tabs, bits):
        for k, v in HEAVIER.items():
            t.controls[k].value = v
        t.controls["bits"].value = b


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGSTOP], ids=["killed", "frozen"])
def test_a_dead_or_hung_worker_is_replaced_and_both_tabs_recover(pooled, sig):
    tabs = [open_tab(pooled), open_tab(pooled)]
    try:
        old = pooled.executor
        victim = _pids(pooled)[0]
        _start_both(tabs, (7, 9))
        time.sleep(0.4)  # both tabs have work in the pool
        os.kill(victim, sig)
        t0 = time.monotonic()
        for t in tabs:
            t.wait(60)
        took = time.monotonic() - t0
        assert pooled.executor is not old and pooled.pool.replacements == 1  # once, not once per tab
        for t, b in zip(tabs, (7, 9)):
            assert t.error is None, t.error  # retried on the new pool
            assert t.frame.bits == b and t.frame.complete and t.frame.values.realizations == 40
        assert took < 45
    finally:
        try:
            os.kill(victim, signal.SIGKILL)
        except OSError:
            pass
        for t in tabs:
            t.close()


def test_a_tab_says_so_when_the_pool_fails_twice(app, monkeypatch):
    import app.dashboard.session as session

    tab = open_tab(app)
    try:
        calls = []

        def failing(*a, **k):
            calls.append(1)
            raise PoolTimeout("a worker process did not finish its task within 3 s (hung?)", app.executor)
            yield  # pragma: no cover

        monkeypatch.setattr(session, "iter_frames", failing)
        tab.set(bits=6)
        assert len(calls) == 2 and "did not finish its task within 3 s" in tab.error and "(twice)" in tab.error
        assert "--task-timeout" in tab.error and "internal error" not in tab.error
        monkeypatch.undo()
        tab.set(bits=7, **SMALL)
        assert tab.error is None and tab.frame.bits == 7
    finally:
        tab.close()


def test_replace_only_replaces_the_failed_pool():
    pool = Pool(1, timeout=5)
    try:
        first = pool.current
        assert pool.replace(first) and pool.current is not first
        second = pool.current
        assert not pool.replace(first)  # a second tab reporting the same failure: nothing happens
        assert pool.current is second and pool.replacements == 1
        assert pool.guarded().submit(abs, -3).result(10) == 3
    finally:
        pool.shutdown()


def test_newer_settings_abandon_pool_work_at_once():
    pool = Pool(1, timeout=30)
    stop = []
    try:
        g = pool.guarded(lambda: bool(stop))
        f = g.submit(time.sleep, 5)
        time.sleep(0.2)
        stop.append(1)
        t0 = time.monotonic()
        with pytest.raises(Superseded):
            f.result(5)
        assert time.monotonic() - t0 < 1.0
    finally:
        pool.shutdown()
