"""Fair turns across tabs: a tab that waits for a compute slot says how many tabs are ahead of it.

No timing limits: every wait is on an event or a state, with :data:`support.HANG_S` as a hang guard.
"""

from __future__ import annotations

import threading

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
        b.controls["bits"].value = 5
        wait_until(lambda: b.controls.status.content.startswith("queued behind 1 tab "), "tab B says it is queued")
        assert not b.session.wait_idle(0)  # still waiting, nothing drawn
        release.set()
        a.wait()
        b.wait()
        assert a.frame.bits == 9 and b.frame.bits == 5
        assert b.controls.status.content.startswith("ready") and b.error is None
    finally:
        release.set()
        for t in tabs:
            t.close()
        app.stop()
