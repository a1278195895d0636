"""Make viser's message buffers safe to push into from many threads at once (viser 1.1.x).

``AsyncMessageBuffer.push`` (viser/infra/_async_message_buffer.py) calls ``self.message_event.set()``
directly from the calling thread, besides scheduling the same call on the event loop with
``call_soon_threadsafe``. ``asyncio.Event.set`` iterates the event's deque of waiting futures, which
the event loop thread appends to and removes from in ``Event.wait``: with several tabs drawing at once
that iteration races the loop ("RuntimeError: deque mutated during iteration") and the push raises
in the tab's worker. A lock on our side cannot help, because the other party is viser's event loop.

:func:`install` gives every buffer an event whose ``set`` only touches the waiters on the loop's own
thread; from any other thread it hands the call to the loop. Nothing is lost: push already schedules
the loop-side ``set`` (directly, or at the end of an atomic block), and viser reads the event only on
the loop (``await message_event.wait()``). Every draw of every tab goes through ``push``, so this is the
one place that makes them all safe.
"""

from __future__ import annotations

import asyncio

__all__ = ["install", "LoopEvent"]


class LoopEvent(asyncio.Event):
    """An ``asyncio.Event`` whose ``set`` from a foreign thread is done by ``loop`` on its own thread."""

    def __init__(self, loop: asyncio.AbstractEventLoop):
        super().__init__()
        self._owner = loop

    def set(self) -> None:
        try:
            running = asyncio.get_running_loop()
        except RuntimeError:
            running = None
        if running is self._owner:
            super().set()
            return
        try:
            self._owner.call_soon_threadsafe(super().set)
        except RuntimeError:  # the loop is closed (server stopping): nobody waits any more
            pass


def install() -> bool:
    """Patch viser's ``AsyncMessageBuffer`` (once); False if this viser has no such class."""
    try:
        from viser.infra import _async_message_buffer as amb
    except ImportError:
        return False
    cls = getattr(amb, "AsyncMessageBuffer", None)
    if cls is None or getattr(cls, "_qsid_loop_event", False):
        return cls is not None
    init = cls.__init__

    def __init__(self, *args, **kwargs):
        init(self, *args, **kwargs)
        self.message_event = LoopEvent(self.event_loop)

    cls.__init__ = __init__
    cls._qsid_loop_event = True
    return True
