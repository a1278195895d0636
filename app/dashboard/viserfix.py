"""What the dashboard needs and viser 1.1's public API lacks, one function per hook (docs/known-issues.rst: why each
exists, the upstream change that would retire it). A hook acts on one server, tab or connection, never on a viser
class. Where this viser lacks what a hook relies on, the hook changes nothing, returns False and warns once
(ViserHookWarning): an upgrade cannot switch a protection off silently (tests/dashboard/test_dashboard_viserfix.py)."""

from __future__ import annotations

import asyncio
import functools
import gc
import warnings
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any, TypeVar

import viser
from viser import _messages

__all__ = ["LoopEvent", "ViserHookWarning", "PHONE_SHEET_CSS", "SHEET_SOURCE", "connection_request", "guard_updates"]
__all__ += ["limit_reads", "phone_sheet_style", "redirect_pages", "refuse_share_requests", "send_plotly_js"]
__all__ += ["set_callback_executor", "show_value", "thread_safe_buffers"]
_warned: set[str] = set()
F = TypeVar("F", bound=Callable[..., bool])


class ViserHookWarning(RuntimeWarning):
    """A hook could not be installed (this viser version lacks what it relies on)."""


def _require(condition: bool) -> None:
    if not condition:
        raise AttributeError("this viser lacks what the hook relies on")


def _hook(name: str, relies_on: str) -> Callable[[F], F]:
    """A hook ``name``: where what it ``relies_on`` is missing (an AttributeError, KeyError or ValueError while it
    installs), False and one warning per process instead."""

    def wrap(fn: F) -> F:
        @functools.wraps(fn)
        def hook(*args: Any, **kwargs: Any) -> bool:
            try:
                return fn(*args, **kwargs)
            except (AttributeError, AssertionError, KeyError, ValueError):  # (AssertionError: viser's own checks)
                if name not in _warned:
                    _warned.add(name)
                    text = f"viser {viser.__version__} has no {relies_on}; switched off: {name} (tested: 1.1.1)"
                    warnings.warn(f"qsid-dashboard: {text}", ViserHookWarning, stacklevel=2)
                return False

        return hook  # type: ignore[return-value]

    return wrap


class LoopEvent(asyncio.Event):
    """An ``asyncio.Event`` whose ``set`` from a foreign thread is run by ``loop`` on its own thread; sets made while
    one is on its way there are merged into it (one wake-up of the loop per burst of pushed messages)."""

    def __init__(self, loop: asyncio.AbstractEventLoop):
        super().__init__()
        self._owner, self._handed = loop, False

    def set(self) -> None:
        try:
            on_loop = asyncio.get_running_loop() is self._owner
        except RuntimeError:
            on_loop = False
        if on_loop:
            super().set()
        elif not self._handed:
            self._handed = True
            try:
                self._owner.call_soon_threadsafe(self._set_on_loop)
            except RuntimeError:  # the loop is closed (server stopping): nobody waits any more
                self._handed = False

    def _set_on_loop(self) -> None:
        self._handed = False  # first: a push after this line schedules a set of its own
        super().set()


def _swap(buffer: Any) -> None:
    old, buffer.message_event = buffer.message_event, LoopEvent(buffer.event_loop)
    buffer.event_loop.call_soon_threadsafe(old.set)  # whoever waits on the old event wakes, on the loop


@_hook("thread-safe message buffers", "ViserServer._websock_server")
def thread_safe_buffers(server: Any) -> bool:
    """A LoopEvent in the broadcast buffer, and in each connection's before its messages flow (on the loop)."""
    server._websock_server.on_client_connect(lambda conn: _swap(conn.get_message_buffer()))
    _swap(server._websock_server.get_message_buffer())
    return True


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
    if conn is not None:
        _require(isinstance(conn.transport.max_size, int))
        conn.transport.max_size = int(nbytes)
    return conn is not None


@_hook("page redirects (short links)", "websockets Server of its own on the port")
def redirect_pages(server: Any, locate: Callable[[str, str, bool], str | None]) -> bool:
    """A 302 to ``locate(target, host, https)`` (if not None) for page requests: wraps the ``process_request`` of
    the websockets ``Server`` on ``server``'s port (public attributes; found among the live objects)."""
    from websockets.asyncio.server import Server
    from websockets.datastructures import Headers
    from websockets.http11 import Response

    port = server.get_port()
    (ws,) = (o for o in gc.get_objects() if type(o) is Server and port in {s.getsockname()[1] for s in o.sockets or ()})
    serve = ws.process_request

    def process_request(connection: Any, request: Any) -> Any:
        if "websocket" not in str(request.headers.get("Upgrade", "")).lower():
            https = str(request.headers.get("X-Forwarded-Proto", "")).lower() == "https"
            where = locate(str(request.path), str(request.headers.get("Host", "") or ""), https)
            if where is not None:
                headers = Headers([("Location", where), ("Cache-Control", "no-store"), ("Content-Length", "0")])
                return Response(302, "Found", headers, b"")
        return serve(connection, request) if serve is not None else None

    if not getattr(serve, "qsid", False):  # (once: a second call keeps the first wrapper)
        ws.process_request, process_request.qsid = process_request, True  # type: ignore[attr-defined]
    return True


@_hook("the per-tab callback queue", "GuiApi._thread_executor")
def set_callback_executor(gui: Any, executor: Any) -> bool:
    """Run one tab's panel callbacks in ``executor`` (``submit(fn, *args)``), not viser's one shared pool."""
    _require(callable(gui._thread_executor.submit))
    gui._thread_executor = executor
    return True


Guard = Callable[[Any, dict, Callable[[], Awaitable[None]]], Awaitable[None]]


@_hook("the explanation of refused values", "GuiApi._handle_gui_updates on GuiApi._websock_interface")
def guard_updates(gui: Any, guard: Guard) -> bool:
    """Route a tab's input messages through ``guard(handle, updates, apply)`` before viser converts the values
    (``apply()``: viser's own handling, awaited; the handle from ``GuiApi._gui_input_handle_from_uuid``)."""
    conn, orig, inputs = gui._websock_interface, gui._handle_gui_updates, gui._gui_input_handle_from_uuid
    _require(isinstance(inputs, dict))
    conn.unregister_handler(_messages.GuiUpdateMessage, orig)

    async def guarded(client_id: int, message: Any) -> None:
        await guard(inputs.get(message.uuid), dict(message.updates), lambda: orig(client_id, message))

    conn.register_handler(_messages.GuiUpdateMessage, guarded)
    return True


@_hook("the refused value's input set back", "GuiApi._websock_interface.queue_message and a handle's _impl.uuid")
def show_value(gui: Any, handle: Any) -> bool:
    """Send the tab of ``gui`` the value input ``handle`` holds: after a refused value the browser would go on
    showing what was typed (viser sends a value only when it changes; the handle keeps the one in use)."""
    gui._websock_interface.queue_message(_messages.GuiUpdateMessage(handle._impl.uuid, {"value": handle.value}))
    return True


@_hook("the refusal of share-URL requests", "share-URL handlers on ViserServer._websock_server")
def refuse_share_requests(server: Any) -> bool:
    """Drop the handlers of "share URL" requests: a hidden button, but any client could open a public tunnel."""
    for kind in (_messages.ShareUrlRequest, _messages.ShareUrlDisconnect):
        server._websock_server.unregister_handler(kind)
    return True


@_hook("the small plotly.js bundle", "GuiApi._websock_interface and GuiApi._setup_plotly_js")
def send_plotly_js(gui: Any, source: str) -> bool:
    """Queue ``source`` (plotly.js) to the tab, marked sent so viser skips its 4.8 MB bundle; False if sent already."""
    _require(isinstance(gui._setup_plotly_js, bool) and callable(gui._websock_interface.queue_message))
    if gui._setup_plotly_js:
        return False
    gui._websock_interface.queue_message(_messages.RunJavascriptMessage(source=source))
    gui._setup_plotly_js = True
    return True


#: viser's phone layout (up to its 36em breakpoint) draws every panel in one bottom sheet, 20em wide and up to 60 %
#: high (inline styles, client/src/ControlPanel/BottomPanel.tsx): stretched across the window, at most half as high.
PHONE_SHEET_CSS = (
    '<style>@media (max-width: 36em) {.mantine-Paper-root[style*="position: fixed"][style*="20em"]'
    "{width: 100vw !important; max-height: 50% !important;}"
    '.mantine-Paper-root[style*="position: fixed"] [style*="width: 20em"]{width: 100vw !important;}'
    # a dropdown's list (the "show" and "lesson" choices) opens as a sheet at the window's foot, always on
    # screen, instead of beside its input in a sheet that may sit half off the window
    ".mantine-Select-dropdown{position: fixed !important; left: 8px !important; right: 8px !important;"
    "top: auto !important; bottom: 8px !important; width: auto !important; max-height: 45vh !important;"
    "overflow-y: auto !important;}"
    ".mantine-Select-dropdown .mantine-Popover-arrow{display: none !important;}"
    "}"
    # viser draws a slider's number box without its slider's "disabled" (a follower's b): inert like the slider
    ".mantine-Flex-root:has(> .mantine-Slider-root [data-disabled]) > .mantine-NumberInput-root"
    "{pointer-events: none; opacity: 0.6;}"
    "</style>"
)
SHEET_SOURCE = ('position: "fixed"', 'width: "20em"', 'maxHeight: "60%"')  # what the selectors rely on


@_hook("the phone sheet across the window", "bottom sheet styled inline 20em wide in its client")
def phone_sheet_style(gui: Any) -> bool:
    """Send the tab :data:`PHONE_SHEET_CSS` (nothing when the installed client's sheet is styled otherwise)."""
    src = Path(viser.__file__).parent / "client" / "src" / "ControlPanel" / "BottomPanel.tsx"
    _require(not src.is_file() or all(s in src.read_text(encoding="utf-8") for s in SHEET_SOURCE))
    gui.add_html(PHONE_SHEET_CSS, order=1e9)  # a style element: nothing drawn, last in the panel
    return True
