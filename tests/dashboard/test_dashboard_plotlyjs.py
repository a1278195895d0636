"""app.dashboard.viewpanel: each tab gets plotly.js's basic bundle (1.2 MB) instead of the full one (4.8 MB)."""

from __future__ import annotations

import threading
import time

import msgspec
import plotly.offline
import viser
import zstandard
from websockets.sync.client import connect

from app.dashboard import DashboardApp, viewpanel
from app.dashboard.session import iter_frames
from app.frames.cache import SharedCache
from app.frames.render import build_figures
from app.settings.values import Values

BASIC_BANNER = "* plotly.js (basic - minified) v"


def _messages(chunks: list) -> list:
    """viser's frames ``[8 B size][8 B zstd size][zstd msgpack {"messages": [...]}]...`` -> the messages."""
    dz = zstandard.ZstdDecompressor()
    out = []
    for raw in chunks:
        if isinstance(raw, bytes) and len(raw) >= 16:
            size = int.from_bytes(raw[8:16], "little")
            out += msgspec.msgpack.decode(dz.decompress(raw[16 : 16 + size])).get("messages", [])
    return out


def test_shipped_bundle_is_the_plotly_js_version_plotly_draws_for():
    version, source = viewpanel._bundle()
    assert version == plotly.offline.get_plotlyjs_version(), (
        "update app/dashboard/assets/plotly-basic.min.js: npm pack plotly.js-basic-dist-min@"
        f"{plotly.offline.get_plotlyjs_version()}"
    )
    assert 0.5e6 < len(source) < 2e6  # the basic bundle, not the 4.8 MB full one
    assert viewpanel.bundle_version("/**\n* plotly.js (basic - minified) v4.1.1\n*/") == "4.1.1"
    assert viewpanel.bundle_version("no banner") == ""


def test_every_view_draws_only_trace_types_of_the_basic_bundle():
    v = Values(trajectories=10, steps=60, realizations=4, mpc_steps=15)
    frame = list(iter_frames(v, SharedCache()))[-1]
    frame.pinned = frame  # the pinned overlay too
    figs = build_figures(frame)
    types = {tr.type for fig in figs.values() for tr in fig.data}
    assert types and types <= set(viewpanel.TRACE_TYPES), types


class _Gui:
    """What send_basic_bundle touches of viser's GuiApi."""

    def __init__(self):
        self._setup_plotly_js = False
        self.sent = []
        self._websock_interface = self

    def queue_message(self, m):
        self.sent.append(m)


def test_sent_once_and_viser_told_or_a_reason_when_versions_differ(monkeypatch):
    gui = _Gui()
    assert viewpanel.send_basic_bundle(gui) is None
    assert gui._setup_plotly_js is True and len(gui.sent) == 1 and "basic - minified" in gui.sent[0].source[:200]
    assert gui.sent[0].source.endswith(viewpanel.ZERO_WIDTH_GUARD)
    assert "sent already" in viewpanel.send_basic_bundle(gui) and len(gui.sent) == 1
    monkeypatch.setattr(plotly.offline, "get_plotlyjs_version", lambda: "9.9.9")
    other = _Gui()
    why = viewpanel.send_basic_bundle(other)
    # the full bundle (what viser would send), with the guard after it
    assert "9.9.9" in why and len(other.sent) == 1 and other._setup_plotly_js is True
    assert other.sent[0].source == plotly.offline.get_plotlyjs() + viewpanel.ZERO_WIDTH_GUARD


def test_a_tab_receives_the_basic_bundle_and_never_the_full_one():
    app = DashboardApp(host="127.0.0.1", port=0, workers=0)
    chunks: list[bytes] = []
    ws = connect(
        app.url.replace("http://", "ws://"),
        subprotocols=[f"viser-v{viser.__version__}"],
        max_size=None,
        open_timeout=120,
    )
    try:

        def read():
            try:
                while True:
                    chunks.append(ws.recv())
            except Exception:
                pass

        threading.Thread(target=read, daemon=True).start()
        ws.send(
            msgspec.msgpack.encode(
                {
                    "type": "ViewerCameraMessage",
                    "wxyz": [1.0, 0.0, 0.0, 0.0],
                    "position": [3.0, 0.0, 0.0],
                    "fov": 1.0,
                    "near": 0.01,
                    "far": 1000.0,
                    "image_height": 900,
                    "image_width": 1400,
                    "look_at": [0.0, 0.0, 0.0],
                    "up_direction": [0.0, 0.0, 1.0],
                }
            )
        )
        (session,) = app.wait_for_sessions(1, timeout=300)
        assert session.views.plotly_js_note is None
        assert session.wait_idle(300)
        time.sleep(0.5)
        scripts = [m["source"] for m in _messages(chunks) if m.get("type") == "RunJavascriptMessage"]
        plotly_js = [js for js in scripts if "plotly.js" in js[:200]]
        assert len(plotly_js) == 1 and BASIC_BANNER in plotly_js[0][:200], [js[:80] for js in plotly_js]
        assert sum(len(c) for c in chunks) < 1.5e6  # all the tab received (compressed), was ~1.8 MB with the full one
    finally:
        ws.close()
        app.stop()
