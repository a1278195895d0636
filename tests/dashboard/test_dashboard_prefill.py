"""Before it prints its URL the server computes and draws a new tab's view once and fetches its own page once."""

from __future__ import annotations

import http.server
import threading
from types import SimpleNamespace

import pytest

from app.dashboard.lifecycle import fetch_page, first_tab, prefill
from app.dashboard.server import DashboardApp
from app.frames.cache import SharedCache
from app.frames.compute import iter_frames
from app.frames.render import Figures
from app.settings.values import Values
from qsid_core.errors import QsidError

SMALL = dict(trajectories=10, steps=60, realizations=4, mpc_steps=15)


def test_a_tab_after_prefill_finds_every_result_in_the_cache():
    v = Values(system="boeing747", bits=5, **SMALL)
    cache = SharedCache()
    assert prefill(v, cache) >= 2  # a "current" frame, then the curves
    before = cache.misses
    frames = list(iter_frames(v, cache))
    assert frames[-1].complete
    assert cache.misses == before  # nothing computed again


def test_prefill_raises_what_the_settings_raise():
    unstable = Values(system="custom", a_text="1.5 0\n0 1.2", b_text="1; 1", trajectories=5, steps=1000)
    with pytest.raises(QsidError, match="spectral radius"):
        prefill(unstable, SharedCache())


def test_the_server_starts_anyway_and_says_why_the_view_was_not_precomputed(capsys):
    unstable = Values(system="custom", a_text="1.5 0\n0 1.2", b_text="1; 1", trajectories=5, steps=1000)
    app = SimpleNamespace(
        host="127.0.0.1", port=1, defaults=unstable, cache=SharedCache(), figures=Figures(), executor=None, tasks=1
    )
    app.prefill = lambda: DashboardApp.prefill(app)
    first_tab(app)  # port 1: nothing listens; no exception either way
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1 and out[0].startswith(
        "qsid dashboard: the first view was not precomputed (simulated states exceed"
    )


class _Page(http.server.BaseHTTPRequestHandler):
    seen: list = []

    def do_GET(self):  # noqa: N802 (the standard library's name)
        _Page.seen.append((self.path, self.headers.get("Accept-Encoding")))
        body = b"<html></html>"
        self.send_response(200)
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *args):
        pass


@pytest.mark.parametrize("host", ["127.0.0.1", "0.0.0.0"])
def test_fetch_page_asks_for_the_compressed_page_over_loopback(host):
    srv = http.server.HTTPServer(("127.0.0.1", 0), _Page)
    t = threading.Thread(target=srv.serve_forever, daemon=True)
    t.start()
    try:
        _Page.seen.clear()
        assert fetch_page(host, srv.server_address[1])
        assert _Page.seen == [("/", "gzip")]
    finally:
        srv.shutdown()
        srv.server_close()
        t.join(10)


def test_fetch_page_is_false_when_nothing_answers():
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # bound, not listening: the connection is refused
        assert fetch_page("127.0.0.1", port, timeout=5.0) is False
