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

HEAVIER = dict(trajectories=200, steps=1000, realizations=50)  # the letter's size: seconds of pool work
LIGHTER = dict(trajectories=20, steps=100, realizations=6)  # milliseconds of work: only a hang times out


def _pids(app) -> list[int]:
    return [p.pid for p in app.executor._processes.values()]


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
            t.wait(240)
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


def test_a_killed_worker_is_replaced_once_and_both_tabs_recover():
    _fault_while_two_tabs_compute(signal.SIGKILL, 120.0, HEAVIER)


def test_frozen_workers_time_out_are_replaced_and_both_tabs_recover():
    _fault_while_two_tabs_compute(signal.SIGSTOP, 6.0, LIGHTER, before=True)


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


def test_a_tab_closed_while_it_is_being_built_is_not_kept(monkeypatch):
    """On a busy server building a tab takes seconds; a tab closed meanwhile used to stay registered for
    good (its worker, panel and plots: the memory kept growing with every batch of new tabs)."""
    import threading

    import msgspec
    import viser
    from websockets.sync.client import connect

    import app.dashboard.server as server

    built = []

    class SlowSession(server.Session):
        def __init__(self, *a, **k):
            time.sleep(2.0)  # the tab closes meanwhile
            super().__init__(*a, **k)
            built.append(self)

    monkeypatch.setattr(server, "Session", SlowSession)
    app = DashboardApp(host="127.0.0.1", port=0, workers=0)
    try:
        ws = connect(app.url.replace("http://", "ws://"), subprotocols=[f"viser-v{viser.__version__}"])
        ws.send(msgspec.msgpack.encode({
            "type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0], "position": [3.0, 0.0, 0.0],
            "fov": 1.0, "near": 0.01, "far": 1000.0, "image_height": 900, "image_width": 1400,
            "look_at": [0.0, 0.0, 0.0], "up_direction": [0.0, 0.0, 1.0]}))
        time.sleep(0.5)
        ws.close()  # before the tab is built
        end = time.monotonic() + 30
        while not built and time.monotonic() < end:
            time.sleep(0.05)
        assert built, "the tab was never built"
        built[0].thread.join(10)
        assert not built[0].thread.is_alive()  # its worker ended
        assert app.sessions == {} and not app._gone
        assert threading.active_count() < 50
    finally:
        app.stop()


def test_newest_settings_win_over_a_hung_task_without_waiting_for_the_timeout():
    """Workers frozen during heavy work, the task timeout out of reach: the tab's newer (small) settings replace
    the busy pool instead of queueing behind the stale task."""
    app = DashboardApp(host="127.0.0.1", port=0, workers=2, task_timeout=100000.0)
    tab, victims = None, []
    try:
        tab = open_tab(app)
        old = app.executor
        for k, v in HEAVIER.items():
            tab.controls[k].value = v
        tab.controls["bits"].value = 7
        time.sleep(1.0)  # the heavy work is in the pool
        victims = _pids(app)
        for v in victims:
            os.kill(v, signal.SIGSTOP)
        for k, v in LIGHTER.items():
            tab.controls[k].value = v
        tab.controls["bits"].value = 5
        tab.wait(240)
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
