"""Every hook into viser's internals (app/dashboard/viserfix.py) installs against the installed viser,
and each one reports (returns False, warns) when what it relies on is missing."""

from __future__ import annotations

import http.client
import re
import sys
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
import viser
from support import HANG_S
from viser import _messages
from viser.infra import _async_message_buffer as amb

from app.dashboard import viserfix
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
    """A bare viser server with one connected client: (server, client)."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    tab = None
    try:
        tab = WsTab(f"http://127.0.0.1:{server.get_port()}")
        end = time.monotonic() + 60
        while not server.get_clients() and time.monotonic() < end:
            time.sleep(0.05)
        (client,) = server.get_clients().values()
        yield server, client
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
        "install": lambda: viserfix.install(),
        "set_callback_executor": lambda: viserfix.set_callback_executor(gui, executor),
        "guard_updates": lambda: viserfix.guard_updates(gui, lambda text, handle: None),
        "limit_reads": lambda: viserfix.limit_reads(server, client.client_id, 4096),
        "refuse_share_requests": lambda: viserfix.refuse_share_requests(server),
        "plotly_js_unsent": lambda: viserfix.plotly_js_unsent(gui),
        "send_plotly_js": lambda: viserfix.send_plotly_js(gui, "/* plotly.js */"),
        "redirect_pages": lambda: viserfix.redirect_pages(server, _moved),
        "phone_sheet_style": lambda: viserfix.phone_sheet_style(gui),
        "fail_unbound_start": lambda: viserfix.fail_unbound_start(),
    }


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
    server, client = live
    gui = client.gui
    with ThreadPoolExecutor(1) as ex, warnings.catch_warnings():
        warnings.simplefilter("error", ViserHookWarning)  # any hook that cannot be installed fails here
        hooks = _hooks(server, client, ex)
        results = {name: hook() for name, hook in hooks.items() if name != "send_plotly_js"}
        assert results == dict.fromkeys(results, True)
        assert amb.AsyncMessageBuffer._qsid_loop_event is True
        assert gui._thread_executor is ex
        handlers = server._websock_server._incoming_handlers
        assert _messages.ShareUrlRequest not in handlers and _messages.ShareUrlDisconnect not in handlers
        assert gui._handle_gui_updates not in gui._websock_interface._incoming_handlers[_messages.GuiUpdateMessage]
        conn = server._websock_server._live_connections[client.client_id]
        assert conn.transport.max_size == 4096
        assert viserfix.send_plotly_js(gui, "/* plotly.js */") is True
        assert viserfix.plotly_js_unsent(gui) is False  # viser will not send its own bundle


def _remove(monkeypatch, server, client, name):
    """Take away what hook ``name`` relies on."""
    gui = client.gui
    if name == "install":
        monkeypatch.delattr(amb, "AsyncMessageBuffer")
    elif name == "set_callback_executor":
        monkeypatch.delattr(gui, "_thread_executor")
    elif name == "guard_updates":
        monkeypatch.delattr(type(gui), "_handle_gui_updates")
    elif name in ("limit_reads", "refuse_share_requests", "redirect_pages"):
        monkeypatch.delattr(server, "_websock_server")
    elif name in ("plotly_js_unsent", "send_plotly_js"):
        monkeypatch.delattr(gui, "_setup_plotly_js")
    elif name == "phone_sheet_style":  # a client whose sheet is drawn otherwise
        monkeypatch.setattr(viserfix, "SHEET_SOURCE", ('maxHeight: "61%"',))
    elif name == "fail_unbound_start":
        from viser.infra import _infra

        monkeypatch.delattr(_infra.WebsockServer, "_background_worker")


@pytest.mark.parametrize(
    "name",
    [
        "install",
        "set_callback_executor",
        "guard_updates",
        "limit_reads",
        "refuse_share_requests",
        "plotly_js_unsent",
        "send_plotly_js",
        "redirect_pages",
        "phone_sheet_style",
        "fail_unbound_start",
    ],
)
def test_a_hook_whose_viser_attribute_is_missing_says_so(live, fresh, monkeypatch, name):
    server, client = live
    with ThreadPoolExecutor(1) as ex:
        hook = _hooks(server, client, ex)[name]
        _remove(monkeypatch, server, client, name)
        with pytest.warns(ViserHookWarning, match=r"viser .* has no .*; switched off: "):
            result = hook()
    assert result in (False, None)


def test_limit_reads_of_a_tab_already_gone_is_no_warning(live, fresh):
    server, client = live
    with warnings.catch_warnings():
        warnings.simplefilter("error", ViserHookWarning)
        assert viserfix.limit_reads(server, client.client_id + 1000, 4096) is False


def test_redirect_pages_answers_page_requests_and_leaves_the_rest_to_viser(live, fresh):
    server, _client = live
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
    assert all(s in text for s in viserfix.SHEET_SOURCE)
    css = viserfix.PHONE_SHEET_CSS
    assert "@media (max-width: 36em)" in css and css.count("20em") == 2
    theme = (src.parents[1] / "AppTheme.ts").read_text(encoding="utf-8")
    assert "breakpoints" not in theme  # Mantine's default xs breakpoint, 36em: where viser's phone layout starts
    assert "<script" not in css and "max-height: 50%" in css


def test_a_server_whose_every_port_is_refused_raises_instead_of_waiting_for_ever(monkeypatch):
    """viser tries the port and the 999 after it; when all are refused its start used to wait for ever (its
    server thread ended without waking it). With the hook (installed with the dashboard) it raises OSError."""
    import errno
    import threading

    import websockets.asyncio.server

    def refused(*args, **kwargs):
        raise OSError(errno.EACCES, "Permission denied")

    monkeypatch.setattr(websockets.asyncio.server, "serve", refused)
    out: list = []

    def start():
        try:
            out.append(viser.ViserServer(host="127.0.0.1", port=1, verbose=False))
        except BaseException as exc:  # noqa: BLE001 -- what it raised is the result
            out.append(exc)

    t = threading.Thread(target=start, daemon=True)
    t.start()
    t.join(HANG_S)
    assert out, "viser's start still waiting (hung)"
    assert isinstance(out[0], OSError) and "no port from 1 to 1000 on 127.0.0.1 could be bound" in str(out[0])
