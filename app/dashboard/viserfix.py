"""Every use of viser's private internals, in one place (viser 1.1.x; pyproject pins ``>=1.1.1,<1.2``).

The dashboard needs a few things viser's public API does not offer: thread-safe message buffers,
a bounded callback queue per tab, an explanation for a value viser refuses, a bounded socket read
per turn, no "share URL" tunnel, a smaller plotly.js bundle, the websocket's request path and page
requests answered with a redirect (view codes in the address). Each hook below is one function with
a comment saying which private names it relies on and why; the rest of the dashboard calls only
these functions. A hook returns True when it is in place; when this viser lacks what the hook relies
on it changes nothing, returns False and warns once (:class:`ViserHookWarning`), so a viser upgrade
cannot switch a protection off silently. ``tests/dashboard/test_dashboard_viserfix.py`` installs every hook
against the installed viser and checks each one reports a missing attribute.

The message-buffer hook (:func:`install`): ``AsyncMessageBuffer.push``
(viser/infra/_async_message_buffer.py) calls ``self.message_event.set()`` directly from the calling
thread, besides scheduling the same call on the event loop with ``call_soon_threadsafe``.
``asyncio.Event.set`` iterates the event's deque of waiting futures, which the event loop thread
appends to and removes from in ``Event.wait``: with several tabs drawing at once that iteration races
the loop ("RuntimeError: deque mutated during iteration") and the push raises in the tab's worker. A
lock on our side cannot help, because the other party is viser's event loop. :func:`install` gives
every buffer an event whose ``set`` only touches the waiters on the loop's own thread; from any other
thread it hands the call to the loop. Nothing is lost: push already schedules the loop-side ``set``
(directly, or at the end of an atomic block), and viser reads the event only on the loop (``await
message_event.wait()``). Every draw of every tab goes through ``push``, so this is the one place
that makes them all safe.
"""

from __future__ import annotations

import asyncio
import warnings
from collections.abc import Awaitable, Callable
from typing import Any

__all__ = [
    "install",
    "check_request_hook",
    "connection_request",
    "redirect_pages",
    "LoopEvent",
    "ViserHookWarning",
    "set_callback_executor",
    "guard_updates",
    "limit_reads",
    "refuse_share_requests",
    "plotly_js_unsent",
    "send_plotly_js",
    "phone_sheet_style",
    "PHONE_SHEET_CSS",
]


class ViserHookWarning(RuntimeWarning):
    """A hook into viser's internals could not be installed (this viser version lacks what it relies on)."""


_warned: set[str] = set()


def _missing(hook: str, what: str) -> bool:
    """Warn (once per hook) that ``hook`` is not installed because ``what`` is missing; returns False."""
    if hook not in _warned:
        _warned.add(hook)
        import viser

        warnings.warn(
            f"qsid-dashboard: viser {viser.__version__} has no {what}; switched off: {hook} (qsid is tested with viser 1.1.1)",
            ViserHookWarning,
            stacklevel=3,
        )
    return False


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


def install() -> bool:
    """Make viser's message buffers safe to push into from many threads (once; see the module docstring).

    Relies on ``viser.infra._async_message_buffer.AsyncMessageBuffer`` setting ``self.event_loop`` and
    ``self.message_event`` in ``__init__``; the wrapped ``__init__`` replaces the event by a :class:`LoopEvent`.
    """
    try:
        from viser.infra import _async_message_buffer as amb
    except ImportError:
        return _missing("thread-safe message buffers", "module viser.infra._async_message_buffer")
    cls: Any = getattr(amb, "AsyncMessageBuffer", None)
    if cls is None:
        return _missing("thread-safe message buffers", "AsyncMessageBuffer")
    if getattr(cls, "_qsid_loop_event", False):
        return True
    init = cls.__init__

    def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
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


def redirect_pages(server: Any, locate: Callable[[str, str, bool], str | None]) -> bool:
    """Answer a page request with a redirect where ``locate(target, host, secure)`` gives an address.

    ``target`` is the request's path and query, ``host`` its Host header, ``secure`` whether a proxy says the page
    was reached over https (``X-Forwarded-Proto``); ``locate`` returns the ``Location`` (a 302, not cached) or
    None (the request is served as before). Websocket upgrades are never touched.

    viser serves its page through the ``process_request`` hook of its ``websockets`` server, a function local
    to ``WebsockServer._background_worker`` (viser/infra/_infra.py), and keeps no reference to that server
    (``websockets.asyncio.server.Server``). The serving coroutine holds it in a local variable while it runs
    (``async with serve(...) as server``); this hook finds it there, on viser's event loop
    (``ViserServer._websock_server._background_event_loop``: the coroutine's frame, through the public
    ``asyncio.all_tasks`` and ``cr_frame``), and wraps the server's ``process_request`` attribute, which
    ``websockets`` reads for every new connection.
    """
    from websockets.asyncio.server import Server
    from websockets.datastructures import Headers
    from websockets.http11 import Response

    loop = getattr(getattr(server, "_websock_server", None), "_background_event_loop", None)
    if not isinstance(loop, asyncio.AbstractEventLoop) or loop.is_closed():
        return _missing("page redirects (short links)", "ViserServer._websock_server._background_event_loop")

    async def find() -> Any:
        for task in asyncio.all_tasks():
            frame = getattr(task.get_coro(), "cr_frame", None)
            for value in dict(getattr(frame, "f_locals", None) or {}).values():
                if isinstance(value, Server):
                    return value
        return None

    try:
        ws = asyncio.run_coroutine_threadsafe(find(), loop).result(timeout=10)
    except Exception:  # the loop stopped, or did not answer
        ws = None
    if ws is None or getattr(ws, "_qsid_redirects", False):
        return bool(ws) or _missing("page redirects (short links)", "its websockets Server in a serving coroutine")
    serve = ws.process_request

    def process_request(connection: Any, request: Any) -> Any:
        if "websocket" not in str(request.headers.get("Upgrade", "")).lower():
            secure = str(request.headers.get("X-Forwarded-Proto", "")).lower() == "https"
            where = locate(str(request.path), str(request.headers.get("Host", "") or ""), secure)
            if where is not None:
                headers = Headers([("Location", where), ("Cache-Control", "no-store"), ("Content-Length", "0")])
                return Response(302, "Found", headers, b"")
        return serve(connection, request) if serve is not None else None

    ws.process_request = process_request
    ws._qsid_redirects = True
    return True


def set_callback_executor(gui: Any, executor: Any) -> bool:
    """Run the input callbacks of one tab's panel (``client.gui``) in ``executor`` instead of viser's shared pool.

    Relies on ``GuiApi._thread_executor``: viser submits every ``def`` callback of the panel to it, once
    per message, so a flooding tab grew viser's one shared queue without bound. ``executor`` needs
    ``submit(fn, *args, **kwargs)``; the dashboard's :class:`~app.dashboard.flow.TabCallbacks` keeps at
    most one queued call per callback.
    """
    if not callable(getattr(getattr(gui, "_thread_executor", None), "submit", None)):
        return _missing("the per-tab callback queue", "GuiApi._thread_executor")
    gui._thread_executor = executor
    return True


def guard_updates(
    gui: Any, on_reject: Callable[[str], None], check: Callable[[Any, Any], str | None] | None = None
) -> bool:
    """Wrap viser's handler of one tab's input messages: a value viser cannot take is explained by ``on_reject``.

    ``check(handle, updates)``, if given, runs first on the values as sent (before viser converts them to
    the input's type): a reason it returns is passed to ``on_reject`` and the message is dropped.

    viser converts each value to the input's type before any callback runs (text sent for a slider,
    a list for a checkbox ...); that error used to end unnoticed in the event loop. Relies on
    ``GuiApi._websock_interface`` (the tab's connection, whose public ``register_handler`` /
    ``unregister_handler`` swap the handler, and ``_incoming_handlers`` to find it),
    ``GuiApi._handle_gui_updates`` (viser's handler of ``viser._messages.GuiUpdateMessage``) and
    ``GuiApi._gui_input_handle_from_uuid`` (to name the input in the explanation).
    """
    try:
        from viser._messages import GuiUpdateMessage
    except ImportError:
        return _missing("the explanation of refused values", "viser._messages.GuiUpdateMessage")
    conn = getattr(gui, "_websock_interface", None)
    orig = getattr(gui, "_handle_gui_updates", None)
    handlers = getattr(conn, "_incoming_handlers", None)
    inputs = getattr(gui, "_gui_input_handle_from_uuid", None)
    if conn is None or orig is None or not isinstance(handlers, dict) or orig not in handlers.get(GuiUpdateMessage, ()):
        return _missing("the explanation of refused values", "GuiApi._handle_gui_updates registered on its connection")
    if not isinstance(inputs, dict):
        return _missing("the explanation of refused values", "GuiApi._gui_input_handle_from_uuid")

    async def checked(client_id: int, message: Any) -> None:
        if check is not None:
            why = check(inputs.get(message.uuid), dict(message.updates))
            if why is not None:
                on_reject(why)
                return
        try:
            await orig(client_id, message)
        except Exception as exc:
            handle = inputs.get(message.uuid)
            label = getattr(handle, "label", None) or "an input"
            sent = ", ".join(f"{k} = {str(v)[:40]!r}" for k, v in dict(message.updates).items())
            on_reject(
                f"{label}: the value sent ({sent}) was refused ({type(exc).__name__}: {str(exc)[:80]}); "
                "the input keeps its last value"
            )

    handler: Callable[[int, Any], Awaitable[None]] = checked
    conn.unregister_handler(GuiUpdateMessage, orig)
    conn.register_handler(GuiUpdateMessage, handler)
    return True


def limit_reads(server: Any, client_id: int, nbytes: int) -> bool:
    """Make the event loop read at most ``nbytes`` of client ``client_id``'s socket per turn.

    ``server`` is the ``viser.ViserServer``. Relies on ``ViserServer._websock_server._live_connections``
    (client id -> the websockets ``ServerConnection``) and on the asyncio selector transport's
    ``max_size`` (its read size, 256 KiB by default): viser turns every message read into tasks before
    the loop does anything else, so one big read of a flooding client made every loop turn long.
    False without a warning when the client is not connected (any more).
    """
    conns = getattr(getattr(server, "_websock_server", None), "_live_connections", None)
    if not isinstance(conns, dict):
        return _missing("the bounded socket reads", "ViserServer._websock_server._live_connections")
    conn = conns.get(client_id)
    if conn is None:  # the tab has gone already: nothing to limit
        return False
    transport = getattr(conn, "transport", None)
    if transport is None or not isinstance(getattr(transport, "max_size", None), int):
        return _missing("the bounded socket reads", "asyncio transport max_size on the client's connection")
    transport.max_size = int(nbytes)
    return True


def refuse_share_requests(server: Any) -> bool:
    """Ignore viser's "share URL" requests from any client.

    The button is hidden, but any client could still send one and make the server open a public tunnel
    through viser's relay (the whole class's server on the internet). Relies on
    ``ViserServer._websock_server._incoming_handlers`` holding the handlers of
    ``viser._messages.ShareUrlRequest`` and ``ShareUrlDisconnect``; they are removed.
    """
    from viser import _messages

    handlers = getattr(getattr(server, "_websock_server", None), "_incoming_handlers", None)
    kinds = [getattr(_messages, name, None) for name in ("ShareUrlRequest", "ShareUrlDisconnect")]
    if not isinstance(handlers, dict) or None in kinds:
        return _missing("the refusal of share-URL requests", "ViserServer._websock_server._incoming_handlers")
    for msg in kinds:
        handlers.pop(msg, None)
    return True


def plotly_js_unsent(gui: Any) -> bool | None:
    """Whether viser has not yet sent plotly.js to the tab of ``gui`` (None: this viser keeps no such flag).

    Relies on ``GuiApi._setup_plotly_js``: False until viser's ``add_plotly`` sends the full bundle.
    """
    flag = getattr(gui, "_setup_plotly_js", None)
    if not isinstance(flag, bool):
        _missing("the small plotly.js bundle", "GuiApi._setup_plotly_js")
        return None
    return not flag


def send_plotly_js(gui: Any, source: str) -> bool:
    """Queue ``source`` (a plotly.js bundle) to the tab of ``gui`` and tell viser it was sent.

    Relies on ``GuiApi._websock_interface.queue_message``, ``viser._messages.RunJavascriptMessage``
    (what viser itself sends the bundle in) and ``GuiApi._setup_plotly_js`` (set True: viser then
    skips sending its own 4.8 MB bundle).
    """
    try:
        from viser._messages import RunJavascriptMessage
    except ImportError:
        return _missing("the small plotly.js bundle", "viser._messages.RunJavascriptMessage")
    conn = getattr(gui, "_websock_interface", None)
    if (
        conn is None
        or not callable(getattr(conn, "queue_message", None))
        or not isinstance(getattr(gui, "_setup_plotly_js", None), bool)
    ):
        return _missing("the small plotly.js bundle", "GuiApi._websock_interface.queue_message")
    conn.queue_message(RunJavascriptMessage(source=source))
    gui._setup_plotly_js = True
    return True


# ----- the phone's bottom sheet -------------------------------------------------------------------------------
#: viser's phone layout (windows up to its 36em breakpoint) puts every panel into one bottom sheet drawn
#: ``position: fixed; width: 20em; max-height: 60%`` (``viser/client/src/ControlPanel/BottomPanel.tsx``, inline
#: styles): plots in it were ~250 px wide and it covered most of the scene. The style sheet below, limited to
#: that breakpoint, stretches the sheet (and the box inside it, also 20em) across the window and caps it at
#: half the window's height; the selectors match those inline styles.
PHONE_SHEET_CSS = (
    "<style>@media (max-width: 36em) {"
    '.mantine-Paper-root[style*="position: fixed"][style*="20em"]'
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
#: What the selectors rely on, as the client's source writes it.
SHEET_SOURCE = ('position: "fixed"', 'width: "20em"', 'maxHeight: "60%"')


def phone_sheet_style(gui: Any) -> bool:
    """Send the tab of ``gui`` the style sheet that widens viser's phone sheet (:data:`PHONE_SHEET_CSS`).

    Relies on the sheet's inline styles (:data:`SHEET_SOURCE`) in ``viser/client/src/ControlPanel/
    BottomPanel.tsx``; when the installed client's source says otherwise, nothing is sent (False, one warning).
    """
    from pathlib import Path

    import viser

    src = Path(viser.__file__).parent / "client" / "src" / "ControlPanel" / "BottomPanel.tsx"
    if src.is_file() and not all(s in src.read_text(encoding="utf-8") for s in SHEET_SOURCE):
        return _missing("the phone sheet across the window", "the bottom sheet's inline width 20em")
    gui.add_html(PHONE_SHEET_CSS, order=1e9)  # a style element: nothing drawn, last in the panel
    return True
