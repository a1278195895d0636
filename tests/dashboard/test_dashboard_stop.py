"""The dashboard's stop path: the pool's workers are always killed and reaped before the process leaves.

The process leaves ``STOP_WAIT`` seconds after a stop signal whatever the web server is doing, but never
before the pool is halted (its workers killed and reaped), even when that takes longer than ``STOP_WAIT``.
"""

from __future__ import annotations

import threading
import time

from app.dashboard import lifecycle


class _SlowApp:
    """Records the stop's steps; its halt and its web server each may outlast ``STOP_WAIT``."""

    def __init__(self, halt_s: float, server_s: float):
        self.steps: list[str] = []
        self.halt_s = halt_s
        self.server_s = server_s
        outer = self

        class _Server:
            def stop(self):
                time.sleep(outer.server_s)
                outer.steps.append("server stopped")

        self.server = _Server()

    def halt(self):
        time.sleep(self.halt_s)
        self.steps.append("halted")
        return []


def test_the_pool_is_halted_even_when_that_outlasts_the_stop_bound(monkeypatch):
    monkeypatch.setattr(lifecycle, "STOP_WAIT", 0.2)
    app = _SlowApp(halt_s=0.7, server_s=0.0)
    lifecycle.stop_app(app)
    assert app.steps[:1] == ["halted"]


def test_a_web_server_that_does_not_stop_does_not_hold_the_process(monkeypatch):
    monkeypatch.setattr(lifecycle, "STOP_WAIT", 0.2)
    block = threading.Event()
    app = _SlowApp(halt_s=0.0, server_s=0.0)
    app.server.stop = block.wait  # never returns until the test ends
    try:
        lifecycle.stop_app(app)
        assert app.steps == ["halted"]
    finally:
        block.set()


def test_the_pool_is_halted_before_the_web_server_stops():
    app = _SlowApp(halt_s=0.0, server_s=0.0)
    lifecycle.stop_app(app)
    deadline = time.monotonic() + 60
    while len(app.steps) < 2 and time.monotonic() < deadline:  # the server's stop may finish after the bound
        time.sleep(0.01)
    assert app.steps == ["halted", "server stopped"]
