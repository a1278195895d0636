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

__all__ = ["install", "LoopEvent", "check_request_hook", "connection_request"]


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


# ----- the websocket's request path (view codes) --------------------------------------------------------------
# viser's client does not tell the server its page URL. It does connect to the websocket address given by the
# page's ``?websocket=`` query parameter, path included, and viser's websocket server accepts any path. The
# server keeps each client's raw connection in ``WebsockServer._live_connections`` (viser/infra/_infra.py,
# filled before the connect callbacks run, emptied on disconnect); the ``websockets`` connection keeps the
# upgrade request (``connection.request``: path and headers). That is the only place the path is visible.


def check_request_hook(server) -> None:
    """Fail loudly (RuntimeError) if this viser no longer keeps the raw connections where
    :func:`connection_request` reads them: view links would silently open default settings."""
    ws = getattr(server, "_websock_server", None)
    if not isinstance(getattr(ws, "_live_connections", None), dict):
        raise RuntimeError(
            "viser internals changed: ViserServer._websock_server._live_connections is missing, so the "
            "dashboard cannot read a tab's view code from its websocket path (app/dashboard/viserfix.py)"
        )


def connection_request(server, client_id) -> tuple[str, str] | None:
    """(path, Host header) of the request that opened ``client_id``'s websocket; None if it is gone already."""
    conn = server._websock_server._live_connections.get(client_id)
    request = getattr(conn, "request", None)
    if request is None:
        return None
    return str(request.path), str(request.headers.get("Host", "") or "")
