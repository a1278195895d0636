"""The dashboard's shared cache (app.frames.cache): a bounded LRU that many threads use, and what it shares."""

from __future__ import annotations

import dataclasses
import threading

import numpy as np
import pytest

from app.dashboard.session import iter_frames
from app.frames.cache import SharedCache
from app.settings.config import sweep_config
from app.settings.values import Values, resolve_system
from qsid_core import Experiment

SMALL = dict(trajectories=10, steps=60, realizations=4, mpc_steps=15)


def frames(v: Values, cache):
    return list(iter_frames(v, cache))


def test_shared_cache_is_a_bounded_lru():
    c = SharedCache(max_bytes=3 * 8000 + 500, keep=1)
    for i in range(5):
        c[("x", i)] = np.zeros(1000)
    assert len(c) == 3 and ("x", 0) not in c and ("x", 4) in c
    _ = c[("x", 2)]  # touch: now the most recent
    c[("x", 5)] = np.zeros(1000)
    assert ("x", 2) in c and ("x", 3) not in c
    assert sorted(c) == [("x", 2), ("x", 4), ("x", 5)]
    with pytest.raises(KeyError):
        c[("missing",)]


def test_shared_cache_survives_threads():
    c = SharedCache(max_bytes=50 * 800, keep=4)

    def work(t):
        for i in range(300):
            c[(t, i)] = np.zeros(100)
            _ = (t, i) in c
            list(c)

    ths = [threading.Thread(target=work, args=(t,)) for t in range(4)]
    for t in ths:
        t.start()
    for t in ths:
        t.join()
    assert len(c) <= 50 and c.nbytes <= 50 * 800 + 4 * 1000


def test_a_weight_change_reuses_the_identified_models():
    """Q/R change: the same identified models come back (no new identification); new closed loops."""
    cache = SharedCache()
    v = Values(**SMALL)
    first = frames(v, cache)[-1]
    other = frames(v.replace(log_q=(0.5, -1.0, -1.0), log_r=(0.0, 0.2)), cache)[-1]
    assert all(other.idents[lab] is first.idents[lab] for lab in first.labels)
    assert other.loops["LS"] is not first.loops["LS"]
    assert other.rows["LS"][4]["mpc_cost"]["mean"] != first.rows["LS"][4]["mpc_cost"]["mean"]


def test_tabs_with_equal_settings_share_results():
    """A second computation with the same settings (another tab) gets the first one's objects."""
    cache = SharedCache()
    v = Values(**SMALL)
    a = frames(v.replace(bits=9), cache)[0]
    ex = Experiment(sweep_config(v, resolve_system(v).system), cache=cache)
    assert ex.identification(9, "ls") is a.idents["LS"] and ex.closed_loops(9, "bcls") is a.loops["BCLS"]
    b = frames(v.replace(data_seed=3), cache)[0]  # other data: other models
    assert b.idents["LS"] is not a.idents["LS"]


def test_a_word_length_change_reuses_the_tabs_rows_and_they_equal_fresh_ones():
    from app.frames.frame import full_row

    cache, memo = SharedCache(), {}
    v = Values(system="dc-motor", bits=4, **SMALL)
    first = list(iter_frames(v, cache, memo=memo))[-1]
    again = list(iter_frames(v.replace(bits=7), cache, memo=memo))[-1]
    for lab in first.rows:
        for b, r in first.rows[lab].items():
            assert again.rows[lab][b] is r  # built once, reused
    assert not any(k[0] == "view-row" for k in cache)  # the tab's own, not in the shared budget
    fresh = frames(v.replace(bits=7), None)[-1]  # no cache at all: built from scratch
    assert fresh.rows == again.rows
    ex = again.ex
    lp = ex.closed_loops(7, "ls")
    assert full_row(ex, "ls", 7, lp, memo) is again.rows["LS"][7]
    other = dataclasses.replace(lp)  # equal numbers, another object: never taken for the cached one
    assert full_row(ex, "ls", 7, other, memo) is not again.rows["LS"][7]
    q = list(iter_frames(v.replace(log_q=(0.3, 0.3, 0.3)), cache, memo=memo))[-1]  # new closed loops: new rows
    assert q.rows["LS"][7] is not again.rows["LS"][7]
