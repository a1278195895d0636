"""Load on a real server over loopback websockets: a soak, a flood, heavy settings interrupted.

These tests assert behaviour only (everyone stays connected, a new tab is drawn during a flood, newer
settings win, the server stops cleanly by itself); every wait is a hang guard of minutes. The figures
a busy machine can break -- RSS levels, seconds until a new tab is ready, how soon light settings
replace heavy ones, how long Ctrl+C takes -- are measured by ``benchmarks/bench_soak.py`` and
``benchmarks/bench_responsiveness.py``, which print them. The clients are plain websocket tabs
(:mod:`benchmarks._wsclient`) sending what a browser sends.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest
from support import HANG_S, open_tab, wait_until

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _wsclient import WsTab  # noqa: E402
from bench_soak import Clients, Server  # noqa: E402

pytestmark = pytest.mark.slow


def _stop(s: Server) -> None:
    """Ctrl+C, and the server ends by itself (exit code 0, not killed) without a traceback."""
    took = s.stop(grace=HANG_S)
    print(f"server stopped {took:.2f} s after SIGINT")
    assert s.p.returncode == 0, f"the server did not end by itself after SIGINT (exit code {s.p.returncode})"
    assert not any("Traceback" in line for line in s.errors), "".join(s.errors)[-3000:]


def test_a_soak_keeps_every_client_connected_and_the_server_answering():
    """3 tabs change settings 10 times a second for 30 s (a 32 MB cache fills in the first seconds):
    nobody is dropped, a new tab is still drawn afterwards, and the server stops cleanly."""
    s = Server("--workers", "2", "--cache-mb", "32")
    try:
        c = Clients(s.url, 3, rate=10.0, timeout=HANG_S)
        wait_until(lambda: c.sent >= 100, "the clients sent 100 changes", every=0.1)
        rss = []
        for _ in range(6):
            time.sleep(5)
            rss.append(s.rss)
        sent, connected, failed = c.sent, c.connected, c.failed
        c.close()
        print(f"soak RSS (MB, every 5 s): {[round(x) for x in rss]}; changes {sent}")
        assert connected == 3 and failed == 0, (connected, failed)
        assert c.sent >= sent >= 100
        tab = WsTab(s.url, timeout=HANG_S)
        try:
            tab.wait_ready(HANG_S)
        finally:
            tab.close()
    finally:
        _stop(s)


def test_a_new_tab_is_drawn_while_three_clients_flood():
    """3 clients send changes as fast as they can; a tab that connects meanwhile is drawn while the flood
    goes on, and nobody is disconnected (it used to wait forever, with keepalive timeouts)."""
    s = Server("--workers", "2")
    try:
        c = Clients(s.url, 3, rate=0, timeout=HANG_S)
        try:
            wait_until(lambda: c.sent >= 300, "the flood started", every=0.05)
            tab = WsTab(s.url, timeout=HANG_S)
            try:
                waited = tab.wait_ready(HANG_S)
                during = c.sent
                wait_until(lambda: c.sent >= during + 100, "the flood went on after the tab was drawn", every=0.05)
            finally:
                tab.close()
            assert c.connected == 3 and c.failed == 0, (c.connected, c.failed)
        finally:
            c.close()
        print(f"flood: new tab ready after {waited:.2f} s; {c.sent} changes sent")
    finally:
        _stop(s)


HEAVY = dict(
    trajectories=400, steps=2000, realizations=100, horizon=50, mpc_steps=300, identification="LS + BCLS"
)  # the largest the panel allows: seconds of work per stage
LIGHT = dict(trajectories=10, steps=60, realizations=4, horizon=10, mpc_steps=15, identification="LS")


def test_heavy_settings_are_interrupted_by_a_newer_light_one():
    """Whatever stage the heavy settings are in (the current b, or the curves), the light ones that follow
    are drawn in full and the tab ends without an error (how soon: benchmarks/bench_responsiveness.py)."""
    from app.dashboard import DashboardApp

    app = DashboardApp(host="127.0.0.1", port=0, workers=2)
    tab = open_tab(app)
    try:
        for seed, delay in ((11, 0.5), (12, 4.0)):  # in the current-b stage, then in the curves
            for k, v in HEAVY.items():
                tab.controls[k].value = v
            tab.controls["data_seed"].value = seed
            time.sleep(delay)
            assert not tab.controls.status.content.startswith("ready"), "the heavy settings finished: not a test"
            t0 = time.monotonic()
            for k, v in LIGHT.items():
                tab.controls[k].value = v
            drawn = []

            def light_drawn() -> bool:
                f = tab.frame
                if f is not None and f.values.data_seed == seed:
                    drawn.append(f.values.trajectories)
                return bool(drawn) and drawn[-1] == LIGHT["trajectories"]

            wait_until(light_drawn, "the light settings were drawn")
            print(f"heavy for {delay} s, then light: drawn after {time.monotonic() - t0:.2f} s")
            assert tab.wait().error is None
            f = tab.frame
            assert f.values.data_seed == seed and f.values.trajectories == LIGHT["trajectories"] and f.complete
    finally:
        tab.close()
        app.stop()
