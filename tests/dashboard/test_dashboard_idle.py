"""Memory given back once the last tab has been gone a while (app.dashboard.lifecycle), and not before."""

from __future__ import annotations

import os
import threading

import numpy as np
from support import HANG_S, alive, open_tab, wait_until

from app.dashboard import lifecycle
from app.dashboard.lifecycle import IdleRelease
from app.dashboard.pool import Pool
from app.frames.cache import SharedCache


def test_release_runs_once_after_the_delay():
    fired = threading.Event()
    idle = IdleRelease(fired.set, delay=0.05)
    idle.schedule()
    assert fired.wait(HANG_S)
    wait_until(lambda: not idle.pending, "the timer forgets itself")
    assert idle.releases == 1


def test_a_tab_opening_meanwhile_cancels_the_release():
    calls: list = []
    idle = IdleRelease(lambda: calls.append(1), delay=3600.0)
    idle.schedule()
    assert idle.pending
    idle.cancel()
    assert not idle.pending and calls == [] and idle.releases == 0


def test_scheduling_again_starts_over_and_releases_once():
    calls: list = []
    done = threading.Event()
    idle = IdleRelease(lambda: (calls.append(1), done.set()), delay=0.2)
    for _ in range(5):
        idle.schedule()
    assert done.wait(HANG_S)
    wait_until(lambda: not idle.pending, "the timer forgets itself")
    assert calls == [1]


def test_shared_cache_clear_forgets_entries_and_their_size():
    c = SharedCache()
    c[("x", 1)] = np.zeros(1000)
    c.clear()
    assert len(c) == 0 and c.nbytes == 0 and ("x", 1) not in c


def test_pool_release_gives_fresh_workers_and_ends_the_old_ones():
    """All the workers held (data of earlier tasks, freed pages) goes back: the old processes are gone."""
    pool = Pool(1, timeout=HANG_S)
    try:
        old = pool.guarded().submit(os.getpid).result(HANG_S)
        pool.release()
        assert pool.guarded().submit(os.getpid).result(HANG_S) != old
        wait_until(lambda: not alive(old), "the old worker ended and was reaped")
        assert pool.replacements == 0  # a release is no failure
    finally:
        pool.shutdown()


def _threads(name: str) -> set:
    return {t for t in threading.enumerate() if t.name == name}


def test_pool_release_without_workers_is_a_no_op():
    before = _threads("qsid-pool-watch")
    pool = Pool(0)
    pool.release()
    assert pool.current is None and pool.guarded() is None
    assert _threads("qsid-pool-watch") == before  # no workers, nothing to watch: no watchdog thread


def test_the_servers_memory_is_trimmed_until_it_halts(monkeypatch):
    """The server's freed pages go back to the system every few seconds (lifecycle.trim_every), until it halts."""
    calls = []
    monkeypatch.setattr(lifecycle, "trim", lambda: bool(calls.append(1)))
    halted, before = threading.Event(), _threads("qsid-trim")
    lifecycle.trim_every(halted, seconds=0.01)
    wait_until(lambda: len(calls) >= 3, "trimmed again and again")
    halted.set()
    wait_until(lambda: _threads("qsid-trim") == before, "the trimming thread ended")


def test_the_last_tab_closing_schedules_the_release_and_a_new_tab_cancels_it(dashboard):
    t = open_tab(dashboard)
    assert not dashboard.idle.pending
    assert len(dashboard.cache) > 0
    t.close()
    wait_until(lambda: dashboard.idle.pending, "release scheduled after the last tab closed")
    t2 = open_tab(dashboard)  # a reload: its results are still there
    assert not dashboard.idle.pending
    t2.close()
    wait_until(lambda: dashboard.idle.pending, "scheduled again")


def test_release_clears_the_results_and_computes_the_default_view_again(dashboard):
    t = open_tab(dashboard)
    t.close()
    wait_until(lambda: dashboard.idle.pending, "release scheduled")
    dashboard.idle.cancel()  # released here, once, whatever the machine's speed
    small = dashboard.defaults.replace(trajectories=5, steps=40, realizations=2, mpc_steps=10)
    dashboard.defaults = small
    dashboard.cache[("sentinel",)] = np.zeros(10)
    dashboard._release_memory()
    assert ("sentinel",) not in dashboard.cache  # cleared
    assert dashboard.cache.kinds().get("data") == 1  # then the default view's results only
    before = dashboard.cache.misses
    dashboard.prefill()  # everything the default view needs is held again
    assert dashboard.cache.misses == before


def test_no_release_while_a_tab_is_open(dashboard):
    t = open_tab(dashboard)
    try:
        dashboard.cache[("sentinel",)] = np.zeros(10)
        dashboard._release_memory()  # e.g. a timer that fired just as a tab opened
        assert ("sentinel",) in dashboard.cache
    finally:
        t.close()
