"""Many tabs drawing at once: viser's message buffer must not race its event loop (viserfix)."""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path

import pytest
import viser

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _wsclient import WsTab  # noqa: E402

from app.dashboard.viserfix import LoopEvent, thread_safe_buffers  # noqa: E402


def test_twelve_tabs_drawing_at_once_never_raise_and_each_shows_its_last_text():
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    clients, tabs, errors = {}, [], []
    try:
        assert thread_safe_buffers(server)  # as the dashboard's server, before any tab connects
        url = f"http://127.0.0.1:{server.get_port()}"
        tabs = [WsTab(url) for _ in range(12)]
        end = time.monotonic() + 30
        while len(server.get_clients()) < 12 and time.monotonic() < end:
            time.sleep(0.05)
        clients = server.get_clients()
        assert len(clients) == 12
        handles = {cid: c.gui.add_markdown("start") for cid, c in clients.items()}
        for cid in clients:
            assert isinstance(clients[cid]._websock_connection.get_message_buffer().message_event, LoopEvent)

        def draw(cid):
            try:
                for i in range(400):
                    handles[cid].content = f"tab {cid} frame {i}"
            except Exception as exc:  # what killed tabs before: RuntimeError deque mutated during iteration
                errors.append(repr(exc))

        threads = [threading.Thread(target=draw, args=(cid,)) for cid in clients]
        for t in threads:
            t.start()
        for t in threads:
            t.join(120)
        assert errors == []
        last = {f"tab {cid} frame 399" for cid in clients}
        end = time.monotonic() + 30
        while time.monotonic() < end and not all(last & set(t.markdown.values()) for t in tabs):
            time.sleep(0.1)
        assert all(last & set(t.markdown.values()) for t in tabs)  # every tab got its final text
    finally:
        for t in tabs:
            t.close()
        server.stop()


def test_loop_event_set_from_another_thread_touches_no_waiter_and_the_loops_set_wakes_them():
    """The race itself, made deterministic: the waiters' deque records which thread iterates it. A set from a
    foreign thread (a tab's worker, through viser's push) does nothing; the same set handed to the loop, as
    viser's push does next (``call_soon_threadsafe``), wakes the waiter, on the loop."""
    import asyncio
    import collections

    seen = []

    class Recording(collections.deque):
        def __iter__(self):
            seen.append(threading.get_ident())
            return super().__iter__()

    loop = asyncio.new_event_loop()
    runner = threading.Thread(target=loop.run_forever, daemon=True)
    runner.start()
    try:
        ev = asyncio.run_coroutine_threadsafe(_make_event(loop), loop).result(10)
        ev._waiters = Recording()
        woke = asyncio.run_coroutine_threadsafe(asyncio.wait_for(ev.wait(), 10), loop)
        time.sleep(0.2)  # the loop waits on the event now
        for _ in range(50):
            ev.set()  # from this (foreign) thread
        time.sleep(0.2)
        assert seen == [] and not ev.is_set() and not woke.done()
        loop.call_soon_threadsafe(ev.set)  # what viser's push does after its direct set
        assert woke.result(10) is True
        assert seen and set(seen) == {runner.ident}
    finally:
        loop.call_soon_threadsafe(loop.stop)
        runner.join(10)
        loop.close()


async def _make_event(loop):
    return LoopEvent(loop)


def test_what_the_loop_event_relies_on_viser_still_does():
    """Every path of viser's message buffer that sets the event from a thread also hands the set to the loop, and
    only the loop waits on the event: a set from a foreign thread can be dropped."""
    import inspect

    from viser.infra._async_message_buffer import AsyncMessageBuffer

    handed = "self.event_loop.call_soon_threadsafe(self.message_event.set)"
    push = inspect.getsource(AsyncMessageBuffer.push)
    assert "self.message_event.set()" in push and handed in push
    for name in ("atomic_end", "set_done"):
        assert handed in inspect.getsource(getattr(AsyncMessageBuffer, name))
    source = inspect.getsource(inspect.getmodule(AsyncMessageBuffer))
    assert source.count("message_event.wait()") == 1 and "message_event.is_set" not in source


# slow (~8 s): three changes computed and drawn in a real tab
@pytest.mark.slow
def test_a_tab_whose_draw_raises_recovers(monkeypatch):
    """An exception inside a draw (as viser's race raised it) is retried at once; failing twice it is one error
    line, and the tab follows its next change."""
    from support import SMALL, Tab

    from app.dashboard import DashboardApp, session

    real, fail = session.Session._draw, {"left": 1}

    def flaky(self, frame, gen):
        if fail["left"] > 0:
            fail["left"] -= 1
            raise RuntimeError("deque mutated during iteration")
        return real(self, frame, gen)

    monkeypatch.setattr(session.Session, "_draw", flaky)
    app = DashboardApp(host="127.0.0.1", port=0, workers=0)
    tab = None
    try:
        tab = Tab(app)
        tab.set(mpc_steps=15, **SMALL)
        tab.wait(120)
        assert fail["left"] == 0 and tab.session.frames_drawn >= 1  # failed once, retried and drawn
        assert tab.session.last_error is None and tab.session.thread.is_alive()
        fail["left"] = 2  # the retry fails as well
        tab.set(bits=5)
        tab.wait(120)
        assert "internal error (RuntimeError)" in (tab.session.last_error or "")
        drawn = tab.session.frames_drawn
        tab.set(bits=6)  # the next change works
        tab.wait(120)
        assert tab.session.thread.is_alive() and tab.session.frames_drawn > drawn
        assert tab.session.last_error is None
    finally:
        if tab is not None:
            tab.close()
        app.stop()
