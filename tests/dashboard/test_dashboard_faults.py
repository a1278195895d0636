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
from support import CAMERA, HANG_S, SMALL, connect_ws, open_tab, pool_workers, wait_until

from app.dashboard import DashboardApp
from app.dashboard.pool import Pool, PoolFailure, Superseded

# slow: stops and kills real pool workers
pytestmark = pytest.mark.slow

HEAVIER = dict(trajectories=200, steps=1000, realizations=50)  # the letter's size: seconds of pool work
LIGHTER = dict(trajectories=20, steps=100, realizations=6)  # milliseconds of work: only a hang times out


def _pids(app) -> list[int]:
    """The pool's workers (children of this process: the server runs in it)."""
    return pool_workers(os.getpid())


def _fault_while_two_tabs_compute(sig, timeout: float, size: dict, before: bool = False) -> None:
    app = DashboardApp(host="127.0.0.1", port=0, workers=2, task_timeout=timeout)
    tabs, victims = [], []
    try:
        tabs = [open_tab(app), open_tab(app)]
        old = app.executor
        # one dead worker breaks the whole pool; a frozen one only hangs its own task: freeze them all
        victims = _pids(app)[:1] if sig == signal.SIGKILL else _pids(app)
        if before:  # the tabs' next tasks go to the frozen workers for sure
            for v in victims:
                os.kill(v, sig)
        for t, b in zip(tabs, (7, 9)):
            for k, v in size.items():
                t.controls[k].value = v
            t.controls["bits"].value = b
        if not before:
            time.sleep(0.5)  # both tabs have work in the pool
            for v in victims:
                os.kill(v, sig)
        for t in tabs:  # a hung task times out, the pool is rebuilt (spawn + imports: slow on a busy machine)
            t.wait(2 * HANG_S)
        assert app.executor is not old and app.pool.replacements >= 1
        if sig == signal.SIGKILL:
            assert app.pool.replacements == 1  # once, not once per tab
        for t, b in zip(tabs, (7, 9)):
            if t.error is None:  # retried on the new pool
                assert t.frame.bits == b and t.frame.complete
                assert t.frame.values.realizations == size["realizations"]
            else:  # a fresh worker's first task (imports, JIT) can itself outlast a short timeout on a busy machine
                assert f"did not finish its task within {timeout:g} s" in t.error and "(twice)" in t.error, t.error
            assert "internal error" not in (t.error or "") and "cannot schedule" not in (t.error or "")
    finally:
        for v in victims:
            try:
                os.kill(v, signal.SIGKILL)
            except OSError:
                pass
        for t in tabs:
            t.close()
        app.stop()


@pytest.mark.slow
def test_a_killed_worker_is_replaced_once_and_both_tabs_recover():
    _fault_while_two_tabs_compute(signal.SIGKILL, 120.0, HEAVIER)


@pytest.mark.slow
def test_frozen_workers_time_out_are_replaced_and_both_tabs_recover():
    _fault_while_two_tabs_compute(signal.SIGSTOP, 6.0, LIGHTER, before=True)


def test_a_tab_says_so_when_the_pool_fails_twice(dashboard, monkeypatch):
    import app.dashboard.session as session

    tab = open_tab(dashboard)
    try:
        calls = []

        def failing(*a, **k):
            calls.append(1)
            raise PoolFailure(
                "a worker process did not finish its task within 3 s (hung?)", None, "... a larger --task-timeout."
            )
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


@pytest.mark.slow
def test_replace_only_replaces_the_failed_pool():
    pool = Pool(1, timeout=HANG_S)  # replace() is tested here, not the task timeout
    try:
        first = pool.current
        assert pool.replace(first) and pool.current is not first
        second = pool.current
        assert not pool.replace(first)  # a second tab reporting the same failure: nothing happens
        assert pool.current is second and pool.replacements == 1
        assert pool.guarded().submit(abs, -3).result(HANG_S) == 3
    finally:
        pool.shutdown()


def test_newer_settings_abandon_pool_work_at_once():
    """The caller is released by newer settings while the task itself would still run for minutes."""
    pool = Pool(1, timeout=4 * HANG_S)  # the watchdog must not be what ends the task
    stop = []
    try:
        g = pool.guarded(lambda: bool(stop))
        f = g.submit(time.sleep, 2 * HANG_S)
        stop.append(1)
        with pytest.raises(Superseded):  # a TimeoutError here would mean it waited for the task
            f.result(HANG_S)
    finally:
        pool.shutdown()


def test_a_tab_closed_while_it_is_being_built_is_not_kept(monkeypatch):
    """On a busy server building a tab takes seconds; a tab closed meanwhile used to stay registered for
    good (its worker, panel and plots: the memory kept growing with every batch of new tabs)."""
    import threading

    import msgspec

    import app.dashboard.server as server

    built, started, release = [], threading.Event(), threading.Event()

    class SlowSession(server.Session):
        def __init__(self, *a, **k):
            started.set()
            release.wait(HANG_S)  # the test closes the tab meanwhile
            super().__init__(*a, **k)
            built.append(self)

    monkeypatch.setattr(server, "Session", SlowSession)
    before = threading.active_count()  # (other tests of this process may have left threads of their own)
    app = DashboardApp(host="127.0.0.1", port=0, workers=0)
    try:
        ws = connect_ws(app)
        ws.send(msgspec.msgpack.encode(CAMERA))
        assert started.wait(HANG_S), "the tab was never started"
        ws.close()  # before the tab is built
        wait_until(lambda: bool(app._gone), "the server saw the tab close")
        release.set()
        wait_until(lambda: bool(built), "the tab was built")
        built[0].thread.join(HANG_S)
        assert not built[0].thread.is_alive()  # its worker ended
        wait_until(lambda: not app._gone, "the closed tab was dropped")
        assert app.sessions == {}
        assert threading.active_count() < before + 45  # the server's own threads, not one per tab built
    finally:
        release.set()
        app.stop()


def _busy(app) -> bool:
    """True once the pool has work of the tab that reached it (queued for or taken by a worker)."""
    return any(task.inner.running() for task in list(app.pool._tasks))


@pytest.mark.parametrize("when", ["mid-task", "idle"])
def test_newest_settings_win_over_a_hung_task_without_waiting_for_the_timeout(when):
    """Workers frozen (during heavy work, or idle before any task reached them), the task timeout out of reach:
    the tab's newer (small) settings replace the frozen pool at once instead of waiting behind it."""
    app = DashboardApp(host="127.0.0.1", port=0, workers=2, task_timeout=100000.0)
    tab, victims = None, []
    try:
        tab = open_tab(app)
        tab.wait()
        old = app.executor
        victims = _pids(app)
        if when == "idle":
            for v in victims:
                os.kill(v, signal.SIGSTOP)
        for k, v in HEAVIER.items():
            tab.controls[k].value = v
        tab.controls["bits"].value = 7
        wait_until(lambda: _busy(app), "the heavy work reached the pool")
        if when == "mid-task":
            for v in victims:
                os.kill(v, signal.SIGSTOP)
        for k, v in LIGHTER.items():
            tab.controls[k].value = v
        tab.controls["bits"].value = 5
        tab.wait()
        assert app.executor is not old and app.pool.replacements >= 1
        assert tab.error is None, tab.error
        assert tab.frame.bits == 5 and tab.frame.values.realizations == LIGHTER["realizations"]
    finally:
        for v in victims:
            try:
                os.kill(v, signal.SIGKILL)
            except OSError:
                pass
        if tab is not None:
            tab.close()
        app.stop()
