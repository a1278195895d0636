"""What the dashboard needs and viser 1.1's public API lacks, one hook per function, each on one server, tab or
connection, never a viser class (why, and the upstream patch that would retire each: ``docs/known-issues.rst``)."""

from __future__ import annotations

import asyncio
import contextlib
import functools
import gc
import warnings
from collections.abc import Awaitable, Callable
from typing import Any, ParamSpec

import viser
from viser import _messages

__all__ = ["LoopEvent", "ViserHookWarning", "connection_request", "guard_updates", "limit_reads"]
__all__ += ["redirect_pages", "refuse_share_requests", "send_plotly_js", "set_callback_executor", "thread_safe_buffers"]
_warned: set[str] = set()  # the hooks that warned
P = ParamSpec("P")


class ViserHookWarning(RuntimeWarning):
    """A hook could not be installed (this viser version lacks what it relies on)."""


def _hook(name: str, relies_on: str) -> Callable[[Callable[P, bool | None]], Callable[P, bool]]:
    """Hook ``name``: True once installed (its body returns None or True), False if its body returns False (nothing to
    do) or if what it ``relies_on`` is missing as it installs: then it changes nothing and warns once per process."""

    def wrap(fn: Callable[P, bool | None]) -> Callable[P, bool]:
        @functools.wraps(fn)
        def hook(*args: P.args, **kwargs: P.kwargs) -> bool:
            try:
                return fn(*args, **kwargs) is not False
            except (AttributeError, AssertionError, KeyError, ValueError):  # (AssertionError: viser's own checks)
                if name not in _warned:
                    _warned.add(name)
                    text = f"viser {viser.__version__} has no {relies_on}; switched off: {name} (tested: 1.1.1)"
                    warnings.warn(f"qsid-dashboard: {text}", ViserHookWarning, stacklevel=2)
                return False

        return hook

    return wrap


class LoopEvent(asyncio.Event):
    """An ``asyncio.Event`` that only its ``loop``'s thread sets (a ``set`` from another thread does nothing)."""

    def __init__(self, loop: asyncio.AbstractEventLoop):
        super().__init__()
        self._owner = loop

    def set(self) -> None:
        with contextlib.suppress(RuntimeError):  # (no loop running in this thread)
            if asyncio.get_running_loop() is self._owner:
                super().set()


@_hook("thread-safe message buffers", "ViserServer._websock_server")
def thread_safe_buffers(server: Any) -> None:
    """A LoopEvent in the broadcast buffer, and in each connection's as it opens (on the loop, before it sends)."""

    def swap(buffer: Any) -> None:
        old, buffer.message_event = buffer.message_event, LoopEvent(buffer.event_loop)
        buffer.event_loop.call_soon_threadsafe(old.set)  # whoever waits on the old event wakes, on the loop

    server._websock_server.on_client_connect(lambda conn: swap(conn.get_message_buffer()))
    swap(server._websock_server.get_message_buffer())


def connection_request(server: Any, client_id: int) -> tuple[str, str] | None:
    """(path, Host) of the request that opened ``client_id``'s websocket (None: gone); RuntimeError: no such hook."""
    conns = getattr(getattr(server, "_websock_server", None), "_live_connections", None)
    if not isinstance(conns, dict):
        raise RuntimeError("viser internals changed: no ViserServer._websock_server._live_connections (viserfix.py)")
    request = getattr(conns.get(client_id), "request", None)
    return None if request is None else (str(request.path), str(request.headers.get("Host", "") or ""))


@_hook("the bounded socket reads", "ViserServer._websock_server._live_connections with the transports' max_size")
def limit_reads(server: Any, client_id: int, nbytes: int) -> bool:
    """Read at most ``nbytes`` of a client's socket per loop turn (False, and no warning, for a client gone)."""
    conn = server._websock_server._live_connections.get(client_id)
    if conn is not None:  # (AttributeError: a transport without a read size)
        conn.transport.max_size = min(conn.transport.max_size, int(nbytes))
    return conn is not None


@_hook("page redirects (short links)", "websockets Server of its own on the port")
def redirect_pages(server: Any, locate: Callable[[str, str, bool], str | None]) -> None:
    """Page requests answered by a 302 to ``locate(target, host, https)`` where that is not None (the websockets
    ``Server`` on ``server``'s port found among the live objects: viser keeps none; its ``process_request`` wrapped)."""
    from websockets.asyncio.server import Server

    port = server.get_port()
    (ws,) = (o for o in gc.get_objects() if type(o) is Server and port in {s.getsockname()[1] for s in o.sockets or ()})
    serve = ws.process_request

    def process_request(connection: Any, request: Any) -> Any:
        head = request.headers
        if "websocket" not in str(head.get("Upgrade", "")).lower():
            https = str(head.get("X-Forwarded-Proto", "")).lower() == "https"
            where = locate(str(request.path), str(head.get("Host", "") or ""), https)
            if where is not None:
                response = connection.respond(302, "")  # (websockets' own plain response, its body empty)
                response.headers.update({"Location": where, "Cache-Control": "no-store"})
                return response
        return serve(connection, request) if serve is not None else None

    if not getattr(serve, "qsid", False):  # (once: a second call keeps the first wrapper)
        ws.process_request, process_request.qsid = process_request, True  # type: ignore[attr-defined]


@_hook("the per-tab callback queue", "GuiApi._thread_executor")
def set_callback_executor(gui: Any, executor: Any) -> None:
    """Run one tab's panel callbacks in ``executor`` (``submit(fn, *args)``), not viser's one shared pool."""
    if gui._thread_executor is not executor:  # (AttributeError: this viser has no such pool)
        gui._thread_executor = executor


@_hook("the refused values explained and set back", "GuiApi._handle_gui_updates on GuiApi._websock_interface")
def guard_updates(gui: Any, guard: Callable[..., Awaitable[bool]], settle: float = 0.0) -> None:
    """A tab's input messages through ``await guard(handle, updates, apply)`` before viser converts them; a value it
    refuses is answered with the input's value in use, ``settle`` s after that input's last message."""
    conn, orig, find = gui._websock_interface, gui._handle_gui_updates, gui._gui_input_handle_from_uuid.get
    send = conn.queue_message
    conn.unregister_handler(_messages.GuiUpdateMessage, orig)
    later: dict[str, asyncio.TimerHandle] = {}  # input uuid -> the sending back of its value in use

    def send_back(uuid: str, handle: Any) -> None:  # (the value in use by then)
        send(_messages.GuiUpdateMessage(uuid, {"value": handle.value}))

    async def guarded(client_id: int, message: Any) -> None:
        handle, uuid = find(message.uuid), message.uuid
        if uuid in later:
            later.pop(uuid).cancel()
        if not await guard(handle, dict(message.updates), lambda: orig(client_id, message)) and handle is not None:
            later[uuid] = asyncio.get_running_loop().call_later(settle, send_back, uuid, handle)

    conn.register_handler(_messages.GuiUpdateMessage, guarded)


@_hook("the refusal of share-URL requests", "share-URL handlers on ViserServer._websock_server")
def refuse_share_requests(server: Any) -> None:
    """Drop the handlers of "share URL" requests: a hidden button, but any client could open a public tunnel."""
    for kind in (_messages.ShareUrlRequest, _messages.ShareUrlDisconnect):
        server._websock_server.unregister_handler(kind)


@_hook("the small plotly.js bundle", "GuiApi._websock_interface and GuiApi._setup_plotly_js")
def send_plotly_js(gui: Any, source: str) -> bool:
    """Queue ``source`` (plotly.js) to the tab, marked sent so viser skips its 4.8 MB bundle; False if sent already."""
    if gui._setup_plotly_js:
        return False
    gui._websock_interface.queue_message(_messages.RunJavascriptMessage(source=source))
    gui._setup_plotly_js = True
    return True
