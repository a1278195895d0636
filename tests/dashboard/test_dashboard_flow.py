"""Back-pressure pieces (:mod:`app.dashboard.flow`), without a server."""

from __future__ import annotations

import threading
import time

from support import HANG_S, wait_until

from app.dashboard.flow import FairSlots, TabCallbacks, inline


def test_inline_callbacks_run_at_once_in_the_callers_thread():
    calls = []
    cb = TabCallbacks("t")
    f = cb.submit(inline(lambda x: calls.append((x, threading.current_thread().name)) or "ok"), 5)
    assert f.done() and f.result() == "ok" and calls == [(5, threading.current_thread().name)]
    cb.shutdown()


def test_a_flood_of_calls_queues_at_most_one_per_callback_with_the_newest_arguments():
    cb = TabCallbacks("t")
    gate, running, seen = threading.Event(), threading.Event(), []

    def slow(x):
        running.set()
        gate.wait(HANG_S)
        seen.append(("slow", x))

    def other(x):
        seen.append(("other", x))

    cb.submit(slow, -1)  # runs in the tab's callback thread and blocks it
    assert running.wait(HANG_S), "the callback thread never ran"
    for i in range(10_000):
        cb.submit(slow, i)
        cb.submit(other, i)
    assert len(cb._queue) == 2 and cb.coalesced == 2 * 10_000 - 2  # bounded: one queued call per callback
    gate.set()
    wait_until(lambda: len(seen) >= 3, "the queued calls ran", every=0.01)
    time.sleep(0.1)
    assert seen == [("slow", -1), ("slow", 9_999), ("other", 9_999)]  # only the newest arguments ran
    cb.shutdown()


def test_errors_of_queued_callbacks_land_in_their_future():
    cb = TabCallbacks("t")
    f = cb.submit(lambda: 1 / 0)
    assert isinstance(f.exception(timeout=HANG_S), ZeroDivisionError)
    f2 = cb.submit(lambda: "still running")
    assert f2.result(timeout=HANG_S) == "still running"
    cb.shutdown()
    assert cb.submit(lambda: 1).result(timeout=HANG_S) is None  # after shutdown: nothing runs


def test_fair_slots_are_handed_out_in_order_nobody_barges_in():
    slots = FairSlots(1)
    order, ready = [], []
    slots.acquire()

    def waiter(k):
        ready.append(k)
        with slots:
            order.append(k)
            time.sleep(0.01)

    threads = []
    for k in range(5):
        t = threading.Thread(target=waiter, args=(k,))
        t.start()
        threads.append(t)
        while len(slots._waiting) < k + 1:  # each in line before the next arrives
            time.sleep(0.005)
    slots.release()
    for _ in range(3):  # the releaser asks again at once: it must queue behind the five
        with slots:
            order.append("again")
    for t in threads:
        t.join(HANG_S)
    assert order[:5] == [0, 1, 2, 3, 4] and order[5:] == ["again"] * 3
