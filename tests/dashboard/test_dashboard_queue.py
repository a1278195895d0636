"""Fair turns across tabs: a tab that waits for a compute slot says how many tabs are ahead of it.

No timing limits: every wait is on an event or a state, with :data:`support.HANG_S` as a hang guard.
"""

from __future__ import annotations

import threading

import pytest
from support import HANG_S, open_tab, wait_until

from app.dashboard import DashboardApp
from app.dashboard.flow import FairSlots


def test_fair_slots_report_the_place_in_the_queue_and_serve_in_order():
    slots = FairSlots(1)
    slots.acquire()  # the first holder
    reports: dict[str, list] = {"b": [], "c": []}
    served: list[str] = []

    def waiter(name: str) -> None:
        with slots.turn(reports[name].append):
            served.append(name)

    tb = threading.Thread(target=waiter, args=("b",))
    tb.start()
    wait_until(lambda: reports["b"] == [1], "b queued behind the holder")
    tc = threading.Thread(target=waiter, args=("c",))
    tc.start()
    wait_until(lambda: reports["c"] == [2], "c queued behind the holder and b")
    slots.release()
    tb.join(HANG_S)
    tc.join(HANG_S)
    assert served == ["b", "c"]  # first come, first served
    assert reports["b"] == [1] and reports["c"][0] == 2 and reports["c"][-1] in (1, 2)
    slots.acquire(lambda n: served.append(f"waited {n}"))  # nobody holds a slot any more: no report
    assert served == ["b", "c"]
    slots.release()


def test_a_tab_behind_a_slow_computation_says_it_is_queued_then_draws(monkeypatch):
    """One compute slot; tab A's computation is held (a fake slow pool); tab B's change says 'queued behind 1 tab'
    while it waits, and B draws its change as soon as A is through."""
    import app.dashboard.session as session

    real = session.iter_frames
    holding, release = threading.Event(), threading.Event()

    def slow_for_nine(values, *a, **k):
        if values.bits == 9:  # tab A's change: the slot is held until the test releases it
            holding.set()
            release.wait(HANG_S)
        yield from real(values, *a, **k)

    app = DashboardApp(host="127.0.0.1", port=0, workers=0, slots=1)
    tabs = []
    try:
        tabs = [open_tab(app), open_tab(app)]
        a, b = tabs
        monkeypatch.setattr(session, "iter_frames", slow_for_nine)
        a.controls["bits"].value = 9
        assert holding.wait(HANG_S), "tab A never started computing"
        b.controls["data_seed"].value = 5  # new data: not cheap, so it waits for the one slot
        wait_until(lambda: b.controls.status.content.startswith("queued behind 1 tab "), "tab B says it is queued")
        assert not b.session.wait_idle(0)  # still waiting, nothing drawn
        release.set()
        a.wait()
        b.wait()
        assert a.frame.bits == 9 and b.frame.values.data_seed == 5
        assert b.controls.status.content.startswith("ready") and b.error is None
    finally:
        release.set()
        for t in tabs:
            t.close()
        app.stop()


def test_cheap_turns_go_first_and_have_a_slot_of_their_own():
    slots = FairSlots(1, fast=1)
    assert slots.acquire() == "slot"  # an expensive computation holds the only ordinary slot
    served: list[str] = []
    reports: dict[str, list] = {"slow": [], "cheap1": [], "cheap2": []}

    def waiter(name: str, cheap: bool) -> None:
        with slots.turn(reports[name].append, cheap):
            served.append(name)
            if name == "cheap1":
                gate.wait(HANG_S)

    gate = threading.Event()
    ts = threading.Thread(target=waiter, args=("slow", False))
    ts.start()
    wait_until(lambda: reports["slow"] == [1], "the ordinary turn waits behind the holder")
    t1 = threading.Thread(target=waiter, args=("cheap1", True))
    t1.start()
    wait_until(lambda: served == ["cheap1"], "a cheap turn is served at once, on the fast slot")
    t2 = threading.Thread(target=waiter, args=("cheap2", True))
    t2.start()
    wait_until(lambda: reports["cheap2"] == [2], "a second cheap turn waits behind the two holders")
    slots.release("slot")  # the expensive holder is done: the freed slot goes to the waiting cheap turn first
    wait_until(lambda: served[:2] == ["cheap1", "cheap2"], "the cheap turn got the freed ordinary slot")
    gate.set()
    for t in (t1, t2, ts):
        t.join(HANG_S)
    assert served == ["cheap1", "cheap2", "slow"]
    assert slots._free == 1 and slots._fast_free == 1  # every slot back


# slow (~4 s): another tab's computation is slowed on purpose
@pytest.mark.slow
def test_a_word_length_change_is_not_queued_behind_another_tabs_slow_computation(monkeypatch):
    """One compute slot held by tab A's slow computation; tab B's word length change redraws from the cache
    on the fast slot at once, while A still holds its slot."""
    import app.dashboard.session as session

    real = session.iter_frames
    holding, release = threading.Event(), threading.Event()

    def slow_for_seed_nine(values, *a, **k):
        if values.data_seed == 9:
            holding.set()
            release.wait(HANG_S)
        yield from real(values, *a, **k)

    app = DashboardApp(host="127.0.0.1", port=0, workers=0, slots=1)
    tabs = []
    try:
        tabs = [open_tab(app), open_tab(app)]
        a, b = tabs
        monkeypatch.setattr(session, "iter_frames", slow_for_seed_nine)
        a.controls["data_seed"].value = 9
        assert holding.wait(HANG_S), "tab A never started computing"
        b.controls["bits"].value = 6
        b.wait()  # drawn while A still holds the only ordinary slot
        assert b.frame.bits == 6 and b.controls.status.content.startswith("ready")
        assert not a.session.wait_idle(0), "A is still computing"
        release.set()
        a.wait()
        assert a.frame.values.data_seed == 9
    finally:
        release.set()
        for t in tabs:
            t.close()
        app.stop()
