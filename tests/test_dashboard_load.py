"""Load on a real server process over loopback websockets: a soak (memory levels off and stays bounded).

Bounded in time (about 60 s). The clients are plain websocket
tabs (:mod:`benchmarks._wsclient`) sending what a browser sends; the longer
version of the soak is ``benchmarks/bench_soak.py``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from bench_soak import Clients, Server  # noqa: E402


def test_soak_memory_levels_off_and_is_released():
    """3 tabs change settings 10 times a second for ~50 s (a 32 MB cache fills in the first seconds)."""
    s = Server("--workers", "2", "--cache-mb", "32")
    try:
        c = Clients(s.url, 3, rate=10.0)
        rss = []
        t0 = time.monotonic()
        while time.monotonic() - t0 < 50:
            time.sleep(5)
            rss.append(s.rss)
        sent, connected = c.sent, c.connected
        c.close()
        time.sleep(5)
        after = s.rss
        print(f"soak RSS (MB, every 5 s): {[round(x) for x in rss]}; after close {after:.0f}; changes {sent}")
        assert sent > 500 and connected == 3
        warm, late = max(rss[2:5]), max(rss[-3:])  # 15-25 s vs the last 15 s
        assert late - warm < 60, f"RSS still growing: {warm:.0f} -> {late:.0f} MB"
        assert max(rss) < 700
        assert after <= late + 10
    finally:
        assert s.stop() < 2.0
    assert not any("Traceback" in line for line in s.errors), "".join(s.errors)[-3000:]
