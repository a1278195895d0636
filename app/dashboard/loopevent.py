"""An ``asyncio.Event`` that any thread may set (viser's message buffers: :func:`app.dashboard.viserfix.install`)."""

from __future__ import annotations

import asyncio

__all__ = ["LoopEvent"]


class LoopEvent(asyncio.Event):
    """An ``asyncio.Event`` whose ``set`` from a foreign thread is done by ``loop`` on its own thread.

    Calls from foreign threads while one is still on its way to the loop are merged into it: every message
    pushed before the loop runs that ``set`` is in the buffer already, so one wake-up serves them all (a
    draw pushes dozens of messages; each hand-over is a write to the loop's self-pipe).
    """

    def __init__(self, loop: asyncio.AbstractEventLoop):
        super().__init__()
        self._owner = loop
        self._handed = False  # a set from a foreign thread is scheduled on the loop and has not run yet

    def set(self) -> None:
        try:
            running = asyncio.get_running_loop()
        except RuntimeError:
            running = None
        if running is self._owner:
            super().set()
            return
        if self._handed:
            return
        self._handed = True
        try:
            self._owner.call_soon_threadsafe(self._set_on_loop)
        except RuntimeError:  # the loop is closed (server stopping): nobody waits any more
            self._handed = False

    def _set_on_loop(self) -> None:
        self._handed = False  # (first: a push after this line schedules a set of its own)
        super().set()
