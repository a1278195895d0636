"""Work under way is joined: threads asking for the same stage result compute it once; a failure is not shared."""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np
import pytest

from qsid_core.control import MPCConfig
from qsid_core.studies import Experiment, Flights, SweepConfig
from qsid_core.studies.flights import memo_joined
from qsid_core.studies.stage_cache import StageCache


class SharedDict(dict):
    """A plain dict that carries flights, as the dashboard's shared cache does."""

    def __init__(self) -> None:
        super().__init__()
        self.flights = Flights()


def _together(n: int, work: Callable[[int], object]) -> list[object]:
    """Run ``work(i)`` in ``n`` threads released at once; their results in order."""
    go = threading.Barrier(n)
    out: list[object] = [None] * n
    errors: list[BaseException] = []

    def run(i: int) -> None:
        go.wait()
        try:
            out[i] = work(i)
        except BaseException as e:  # noqa: BLE001 - reported below
            errors.append(e)

    threads = [threading.Thread(target=run, args=(i,)) for i in range(n)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert not any(t.is_alive() for t in threads), "a thread still waits: a flight was never ended"
    if errors:
        raise errors[0]
    return out


def test_equal_requests_compute_once() -> None:
    shared = SharedDict()
    calls = []
    started = threading.Event()

    def make() -> str:
        calls.append(1)
        started.set()
        threading.Event().wait(0.2)  # long enough for the others to arrive while it runs
        return "value"

    out = _together(8, lambda i: memo_joined(shared, ("k",), make))
    assert out == ["value"] * 8
    assert len(calls) == 1
    assert shared.flights.joined >= 1
    assert len(shared.flights) == 0


def test_a_failed_owner_sends_its_waiters_to_compute_it_themselves() -> None:
    shared = SharedDict()
    calls: list[int] = []
    lock = threading.Lock()

    def make() -> str:
        with lock:
            calls.append(1)
            first = len(calls) == 1
        threading.Event().wait(0.1)
        if first:
            raise RuntimeError("the first owner fails")
        return "value"

    results: list[object] = []

    def work(i: int) -> object:
        try:
            return memo_joined(shared, ("k",), make)
        except RuntimeError as e:
            return e

    results = _together(5, work)
    failed = [r for r in results if isinstance(r, RuntimeError)]
    assert len(failed) == 1  # only the owner that failed sees its failure
    assert results.count("value") == 4
    assert 2 <= len(calls) <= 5
    assert len(shared.flights) == 0


def test_a_batch_joins_keys_under_way_and_releases_what_it_did_not_deliver() -> None:
    shared = SharedDict()
    cache = StageCache(shared)
    computed: list[int] = []
    lock = threading.Lock()

    def compute(todo: list[int], deliver: Callable[[int, object], None]) -> None:
        with lock:
            computed.extend(todo)
        threading.Event().wait(0.1)
        for k in todo:
            deliver(k, k * 10)

    keys = {b: ("stage", b) for b in range(1, 9)}
    out = _together(4, lambda i: cache.batch(keys, compute))
    assert all(o == {b: b * 10 for b in range(1, 9)} for o in out)
    assert sorted(computed) == list(range(1, 9))  # every key computed exactly once

    def half(todo: list[int], deliver: Callable[[int, object], None]) -> None:
        deliver(todo[0], "only the first")

    with pytest.raises(RuntimeError, match="no result"):
        cache.batch({1: ("other", 1), 2: ("other", 2)}, half)
    assert len(shared.flights) == 0  # the key not delivered was released


def test_tabs_with_equal_settings_share_one_computation_of_every_stage() -> None:
    cfg = SweepConfig(bits="3,5", realizations=3, trajectories=8, steps=60, mpc=MPCConfig(steps=15))
    shared = SharedDict()
    alone = Experiment(cfg)

    def tab(i: int) -> object:
        ex = Experiment(cfg, cache=shared)
        return ex.closed_loops_many([3, 5]), ex.identification(5)

    out = _together(4, tab)
    ref_loops, ref_ident = alone.closed_loops_many([3, 5]), alone.identification(5)
    for loops, ident in out:  # type: ignore[misc]
        assert loops[3] is out[0][0][3]  # one object: computed once, handed to every tab  # type: ignore[index]
        np.testing.assert_array_equal(loops[5].cost, ref_loops[5].cost)
        np.testing.assert_array_equal(ident.A_hat, ref_ident.A_hat)
    assert len(shared.flights) == 0
