"""Every hook into viser's internals (app/dashboard/viserfix.py) installs against the installed viser, patches no
viser class, and each one reports (returns False, warns) when what it relies on is missing."""

from __future__ import annotations

import asyncio
import http.client
import inspect
import re
import sys
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
import viser
from viser import _messages
from viser.infra import _async_message_buffer as amb

from app.dashboard import phone, viserfix
from app.dashboard.viserfix import ViserHookWarning

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _wsclient import WsTab  # noqa: E402


@pytest.fixture
def live():
    """A bare viser server with thread-safe buffers (as the dashboard's) and one connected client: (server, client,
    the client's end of the websocket)."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    tab = None
    try:
        assert viserfix.thread_safe_buffers(server) is True
        tab = WsTab(f"http://127.0.0.1:{server.get_port()}")
        end = time.monotonic() + 60
        while not server.get_clients() and time.monotonic() < end:
            time.sleep(0.05)
        (client,) = server.get_clients().values()
        yield server, client, tab
    finally:
        if tab is not None:
            tab.close()
        server.stop()


@pytest.fixture
def fresh(monkeypatch):
    """Each hook warns once per process: forget earlier warnings."""
    monkeypatch.setattr(viserfix, "_warned", set())


def _hooks(server, client, executor):
    gui = client.gui
    return {
        "thread_safe_buffers": lambda: viserfix.thread_safe_buffers(server),
        "set_callback_executor": lambda: viserfix.set_callback_executor(gui, executor),
        "guard_updates": lambda: viserfix.guard_updates(gui, _passes),
        "limit_reads": lambda: viserfix.limit_reads(server, client.client_id, 4096),
        "refuse_share_requests": lambda: viserfix.refuse_share_requests(server),
        "send_plotly_js": lambda: viserfix.send_plotly_js(gui, "/* plotly.js */"),
        "redirect_pages": lambda: viserfix.redirect_pages(server, _moved),
    }


async def _passes(handle, updates, apply):
    """A guard of input messages that lets every one through to viser."""
    await apply()
    return True


async def _at_most_ten(handle, updates, apply):
    """A guard that refuses a value above 10 (before viser converts it) and lets the others through."""
    if float(updates.get("value", 0)) > 10:
        return False
    await apply()
    return True


def _moved(target: str, host: str, secure: bool) -> str | None:
    """A page-redirect rule for the tests: ``/moved`` goes elsewhere (naming the host and the scheme)."""
    return f"/?to={'wss' if secure else 'ws'}://{host}/there" if target.startswith("/moved") else None


def _get(server, target: str, **headers) -> tuple[int, str | None, int]:
    """(status, Location, body size) of a plain GET of ``target`` (redirects not followed)."""
    conn = http.client.HTTPConnection("127.0.0.1", server.get_port(), timeout=60)
    try:
        conn.request("GET", target, headers=headers)
        r = conn.getresponse()
        return r.status, r.getheader("Location"), len(r.read())
    finally:
        conn.close()


def test_the_installed_viser_is_in_the_pinned_range_the_hooks_were_written_for():
    pin = next(
        d for d in tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"] if "viser" in d
    )
    assert pin.replace(" ", "") == "viser>=1.1.1,<1.2"
    major, minor, patch = (int(x) for x in re.findall(r"\d+", viser.__version__)[:3])
    assert (1, 1, 1) <= (major, minor, patch) < (1, 2, 0), viser.__version__


def test_every_hook_installs_against_the_installed_viser(live, fresh):
    server, client, _tab = live
    gui = client.gui
    with ThreadPoolExecutor(1) as ex, warnings.catch_warnings():
        warnings.simplefilter("error", ViserHookWarning)  # any hook that cannot be installed fails here
        hooks = _hooks(server, client, ex)
        before = _class_attributes()
        results = {name: hook() for name, hook in hooks.items()}
        assert results == dict.fromkeys(results, True)
        assert _class_attributes() == before  # every hook acts on one server, tab or connection: no class patched
        assert isinstance(client._websock_connection.get_message_buffer().message_event, viserfix.LoopEvent)
        assert isinstance(server._websock_server.get_message_buffer().message_event, viserfix.LoopEvent)
        assert type(amb.AsyncMessageBuffer(asyncio.new_event_loop(), False).message_event) is asyncio.Event
        assert gui._thread_executor is ex
        handlers = server._websock_server._incoming_handlers
        assert _messages.ShareUrlRequest not in handlers and _messages.ShareUrlDisconnect not in handlers
        assert gui._handle_gui_updates not in gui._websock_interface._incoming_handlers[_messages.GuiUpdateMessage]
        conn = server._websock_server._live_connections[client.client_id]
        assert conn.transport.max_size == 4096
        assert gui._setup_plotly_js is True  # viser will not send its own bundle
        assert viserfix.send_plotly_js(gui, "/* plotly.js */") is False  # sent once


def _class_attributes() -> dict:
    """Every attribute of every class of viser's modules (and of websockets' server), to see that none changes."""
    import websockets.asyncio.server as wss

    mods = [m for name, m in sys.modules.items() if name == "viser" or name.startswith("viser.")] + [wss]
    classes = {c for m in mods for _, c in inspect.getmembers(m, inspect.isclass)}
    return {f"{c.__module__}.{c.__qualname__}": dict(vars(c)) for c in classes}


def test_the_module_scans_no_frame_and_names_its_private_viser_names_in_the_known_issues():
    source = inspect.getsource(viserfix)
    assert "f_locals" not in source and "cr_frame" not in source and "__init__ =" not in source
    names = set(re.findall(r"\b(_[a-z][a-z_]+)\b", source)) - {"_hook", "_require", "_warned", "_owner"}
    notes = (ROOT / "docs" / "known-issues.rst").read_text(encoding="utf-8")
    assert names and all(n in notes for n in names), sorted(n for n in names if n not in notes)


def _remove(monkeypatch, server, client, name):
    """Take away what hook ``name`` relies on."""
    gui = client.gui
    if name == "thread_safe_buffers":
        monkeypatch.delattr(server, "_websock_server")
    elif name == "set_callback_executor":
        monkeypatch.delattr(gui, "_thread_executor")
    elif name == "guard_updates":
        monkeypatch.delattr(type(gui), "_handle_gui_updates")
    elif name in ("limit_reads", "refuse_share_requests"):
        monkeypatch.delattr(server, "_websock_server")
    elif name == "redirect_pages":  # no websockets server listens on the port it is asked for
        monkeypatch.setattr(server, "get_port", lambda: 1)
    elif name == "send_plotly_js":
        monkeypatch.delattr(gui, "_setup_plotly_js")


@pytest.mark.parametrize(
    "name",
    [
        "thread_safe_buffers",
        "set_callback_executor",
        "guard_updates",
        "limit_reads",
        "refuse_share_requests",
        "send_plotly_js",
        "redirect_pages",
    ],
)
def test_a_hook_whose_viser_attribute_is_missing_says_so(live, fresh, monkeypatch, name):
    server, client, _tab = live
    with ThreadPoolExecutor(1) as ex:
        hook = _hooks(server, client, ex)[name]
        _remove(monkeypatch, server, client, name)
        with pytest.warns(ViserHookWarning, match=r"viser .* has no .*; switched off: "):
            result = hook()
    assert result in (False, None)


def test_limit_reads_of_a_tab_already_gone_is_no_warning(live, fresh):
    server, client, _tab = live
    with warnings.catch_warnings():
        warnings.simplefilter("error", ViserHookWarning)
        assert viserfix.limit_reads(server, client.client_id + 1000, 4096) is False


def test_redirect_pages_answers_page_requests_and_leaves_the_rest_to_viser(live, fresh):
    server, _client, _tab = live
    port = server.get_port()
    assert _get(server, "/moved")[0] == 404  # viser itself has no such page
    with warnings.catch_warnings():
        warnings.simplefilter("error", ViserHookWarning)
        assert viserfix.redirect_pages(server, _moved) is True
        assert viserfix.redirect_pages(server, _moved) is True  # once is enough: not wrapped twice
    assert _get(server, "/moved?x=1") == (302, f"/?to=ws://127.0.0.1:{port}/there", 0)
    assert _get(server, "/moved", **{"X-Forwarded-Proto": "https"})[1] == f"/?to=wss://127.0.0.1:{port}/there"
    status, where, size = _get(server, "/")
    assert status == 200 and where is None and size > 1000  # viser's page, as before
    tab = WsTab(f"http://127.0.0.1:{port}/moved")  # a websocket at any path is never redirected
    try:
        end = time.monotonic() + 60
        while len(server.get_clients()) < 2 and time.monotonic() < end:
            time.sleep(0.05)
        assert len(server.get_clients()) == 2
    finally:
        tab.close()


def test_the_phone_sheet_style_matches_the_installed_clients_sheet():
    """The style sheet's selectors match the inline styles of viser's bottom sheet, as its client source writes
    them (the browser test, tests/system/test_dashboard_legibility.py, measures the plots' width in it)."""
    src = Path(viser.__file__).parent / "client" / "src" / "ControlPanel" / "BottomPanel.tsx"
    text = src.read_text(encoding="utf-8")
    assert all(s in text for s in phone.SHEET_SOURCE)
    css = phone.PHONE_SHEET_CSS
    assert "@media (max-width: 36em)" in css and css.count("20em") == 2
    theme = (src.parents[1] / "AppTheme.ts").read_text(encoding="utf-8")
    assert "breakpoints" not in theme  # Mantine's default xs breakpoint, 36em: where viser's phone layout starts
    assert "<script" not in css and "max-height: 50%" in css


def test_guard_updates_sends_a_refused_values_input_back_the_value_in_use(live, fresh):
    """The browser shows what was typed; after a refusal the tab is sent the value the input holds (viser sends a
    value only when it changes), and a value taken goes through viser as before."""
    server, client, tab = live
    number = client.gui.add_number("n", 1.0)
    seen = []
    number.on_update(lambda e: seen.append(e.target.value))
    with warnings.catch_warnings():
        warnings.simplefilter("error", ViserHookWarning)
        assert viserfix.guard_updates(client.gui, _at_most_ten) is True
    tab.wait_for("n")
    tab.send("n", 99.0)  # refused: the tab's copy says 99 until the server sends 1.0 back
    end = time.monotonic() + 60
    while tab.value("n") != 1.0 and time.monotonic() < end:
        time.sleep(0.02)
    assert tab.value("n") == 1.0 and number.value == 1.0
    tab.send("n", 5.0)  # taken
    while number.value != 5.0 and time.monotonic() < end:
        time.sleep(0.02)
    assert number.value == 5.0 and tab.value("n") == 5.0
    while not seen and time.monotonic() < end:
        time.sleep(0.02)
    assert seen == [5.0]  # the refused value reached no callback
