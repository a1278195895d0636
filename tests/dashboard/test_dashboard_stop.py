"""The dashboard's stop path: the pool's semaphores are always released before the process leaves.

The process leaves ``STOP_WAIT`` seconds after a stop signal whatever the web server is doing, but never
while the semaphores' finalizers run: a semaphore unlinked and not yet unregistered makes the resource
tracker warn of a "leaked" semaphore (seen once in a loaded CI run of the SIGHUP test).
"""

from __future__ import annotations

import threading
import time

from app.dashboard import server


class _SlowApp:
    """Records the stop's steps; its pool release and its web server each outlast ``STOP_WAIT``."""

    def __init__(self, release_s: float, server_s: float):
        self.steps: list[str] = []
        self.release_s = release_s
        self.server_s = server_s
        outer = self

        class _Server:
            def stop(self):
                time.sleep(outer.server_s)
                outer.steps.append("server stopped")

        self.server = _Server()

    def halt(self):
        self.steps.append("halted")
        return []

    def release(self):
        time.sleep(self.release_s)
        self.steps.append("released")


def test_the_semaphores_are_released_even_when_that_outlasts_the_stop_bound(monkeypatch):
    monkeypatch.setattr(server, "STOP_WAIT", 0.2)
    app = _SlowApp(release_s=0.7, server_s=0.0)
    monkeypatch.setattr(server, "release_ipc", app.release)
    server._stop_app(app)
    assert app.steps[:2] == ["halted", "released"]


def test_a_web_server_that_does_not_stop_does_not_hold_the_process(monkeypatch):
    monkeypatch.setattr(server, "STOP_WAIT", 0.2)
    block = threading.Event()
    app = _SlowApp(release_s=0.0, server_s=0.0)
    app.server.stop = block.wait  # never returns until the test ends
    monkeypatch.setattr(server, "release_ipc", app.release)
    try:
        server._stop_app(app)
        assert app.steps == ["halted", "released"]
    finally:
        block.set()


def test_the_pool_is_released_before_the_web_server_stops(monkeypatch):
    app = _SlowApp(release_s=0.0, server_s=0.0)
    monkeypatch.setattr(server, "release_ipc", app.release)
    server._stop_app(app)
    deadline = time.monotonic() + 60
    while len(app.steps) < 3 and time.monotonic() < deadline:  # the server's stop may finish after the bound
        time.sleep(0.01)
    assert app.steps == ["halted", "released", "server stopped"]
