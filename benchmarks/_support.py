"""Helpers the benchmarks and the tests share: what a browser sends first, a websocket speaking viser's
protocol, the dashboard as a child process, and the process tree read from /proc.

The tests import this module too (``tests/support.py`` and the whole-process tests in ``tests/system``), so
a benchmark and the test of the same behaviour start the server, open a tab and count leftover processes the
same way. It lives with the benchmarks because they must run without pytest or the test tree; nothing here
imports either. Every wait takes its limit from the caller: a benchmark's limit is part of what it measures,
a test's is only a guard against a hang.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

__all__ = [
    "CAMERA",
    "ROOT",
    "DashboardProcess",
    "alive",
    "children",
    "connect_ws",
    "descendants",
    "family",
    "family_rss",
    "gone_within",
    "rss_mb",
    "stop_tree",
]

ROOT = Path(__file__).resolve().parents[1]

#: What a browser sends first; viser counts a client as connected once it reports its camera.
CAMERA = {
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

#: The line the dashboard prints once it serves (viser prints its own address earlier).
READY_LINE = "qsid dashboard: http"


def connect_ws(url: str, open_timeout: float = 120.0, **kwargs: Any) -> Any:
    """A raw websocket to the dashboard at ``url`` (``http://…``) speaking viser's protocol (nothing sent yet).

    Like a browser it sends no keepalive pings of its own (websockets' client would, and would close the
    connection if a busy server answered one late); it answers the server's pings.
    """
    import viser
    from websockets.sync.client import connect

    kwargs.setdefault("ping_interval", None)
    return connect(
        url.replace("http://", "ws://"),
        subprotocols=[f"viser-v{viser.__version__}"],
        max_size=None,
        open_timeout=open_timeout,
        **kwargs,
    )


# ----- the process tree, from /proc ------------------------------------------------------------------------------
def children(pid: int) -> list[int]:
    """The direct children of ``pid``."""
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    if int(f.read().rsplit(")", 1)[1].split()[1]) == pid:
                        out.append(int(d))
            except (OSError, ValueError, IndexError):
                pass
    return out


def descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (children, their children, ...)."""
    kids: dict[int, list[int]] = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    kids.setdefault(int(f.read().rsplit(")", 1)[1].split()[1]), []).append(int(d))
            except (OSError, ValueError, IndexError):
                pass
    stack, out = [pid], []
    while stack:
        for c in kids.get(stack.pop(), []):
            out.append(c)
            stack.append(c)
    return out


def pool_workers(pid: int) -> list[int]:
    """The worker processes of the process pools (:func:`app.procs.process_pool`, loky's) started by ``pid``."""
    out = []
    for c in children(pid):
        try:
            with open(f"/proc/{c}/cmdline", "rb") as f:
                if b"loky.backend.popen_loky" in f.read():
                    out.append(c)
        except OSError:
            pass
    return sorted(out)


def family(pid: int) -> list[int]:
    """``pid`` and all its descendants."""
    return [pid, *descendants(pid)]


def alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie does not)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def gone_within(pids: list[int], seconds: float) -> list[int]:
    """The pids still alive after waiting up to ``seconds`` (polling)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end and any(alive(p) for p in pids):
        time.sleep(0.2)
    return [p for p in pids if alive(p)]


def rss_mb(pid: int) -> float:
    """Resident memory of process ``pid`` (MB; NaN for a zombie)."""
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def family_rss(pid: int) -> tuple[float, float]:
    """(RSS of ``pid``, RSS of all its descendants) in MB."""
    rest = 0.0
    for p in descendants(pid):
        try:
            mb = rss_mb(p)
        except OSError:  # ended meanwhile
            continue
        if mb == mb:  # a zombie (a replaced worker not yet reaped) has no resident memory
            rest += mb
    return rss_mb(pid), rest


def stop_tree(proc: subprocess.Popen[str], sig: int = signal.SIGTERM, grace: float = 30.0) -> tuple[float, int]:
    """Send ``sig`` to ``proc`` (the server's graceful stop), kill it after ``grace`` s; then wait up to
    ``grace`` s for the processes it had started. Returns (seconds until ``proc`` ended, how many of its
    processes outlived it: those are killed)."""
    desc = descendants(proc.pid)
    t0 = time.monotonic()
    if proc.poll() is None:
        proc.send_signal(sig)
        try:
            proc.wait(timeout=grace)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)
    took = time.monotonic() - t0
    left = gone_within(desc, grace)
    for p in left:
        try:
            os.kill(p, signal.SIGKILL)
        except OSError:
            pass
    return took, len(left)


class DashboardProcess:
    """``python -m app.dashboard --port PORT ARGS`` (loopback, cwd = the repository) until it prints its URL.

    ``url`` and ``pid`` once it serves; ``started_s`` is the time from start to that line; ``errors`` and
    ``output`` collect its stderr lines and the stdout lines after the URL (read in threads, so the pipes
    never fill).

    Parameters
    ----------
    args : str
        Extra options of ``qsid-dashboard``.
    port : int
        0: the server picks a free port.
    env : dict, optional
        The environment (default: this one, with the repository on ``PYTHONPATH``).
    timeout : float
        Seconds to wait for the URL (RuntimeError after that, the process stopped).
    """

    def __init__(self, *args: str, port: int = 0, env: dict[str, str] | None = None, timeout: float = 300.0):
        t0 = time.perf_counter()
        self.p = subprocess.Popen(
            [sys.executable, "-m", "app.dashboard", "--port", str(port), *args],
            cwd=ROOT,
            env=env if env is not None else dict(os.environ, PYTHONPATH=str(ROOT)),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        self.pid = self.p.pid
        self.errors: list[str] = []
        assert self.p.stdout is not None and self.p.stderr is not None
        self._stderr = threading.Thread(target=self.errors.extend, args=(self.p.stderr,), daemon=True)
        self._stderr.start()
        line, end = "", time.monotonic() + timeout
        while not line.startswith(READY_LINE) and time.monotonic() < end and self.p.poll() is None:
            line = self.p.stdout.readline()
        if not line.startswith(READY_LINE):
            self.stop()
            raise RuntimeError(f"the dashboard did not start: {''.join(self.errors)[-2000:]}")
        self.started_s = time.perf_counter() - t0
        self.url = line.split()[2]
        self.output: list[str] = []  # stdout after the URL line
        self._stdout = threading.Thread(target=self.output.extend, args=(self.p.stdout,), daemon=True)
        self._stdout.start()

    def stop(self, sig: int = signal.SIGINT, grace: float = 15.0) -> float:
        """Send ``sig``; seconds until the server ended (killed after ``grace`` s)."""
        t0 = time.monotonic()
        if self.p.poll() is None:
            self.p.send_signal(sig)
            try:
                self.p.wait(grace)
            except subprocess.TimeoutExpired:
                self.p.kill()
                self.p.wait(5)
        return time.monotonic() - t0

    def stderr(self, timeout: float) -> str:
        """Everything the server wrote to stderr, once it has ended (waits up to ``timeout`` s for that)."""
        self.p.wait(timeout)
        self._stderr.join(timeout)
        return "".join(self.errors)

    def stdout(self, timeout: float) -> str:
        """What the server wrote to stdout after its URL line, once it has ended (waits up to ``timeout`` s)."""
        self.p.wait(timeout)
        self._stdout.join(timeout)
        return "".join(self.output)

    def kill(self) -> None:
        """SIGKILL the server (its children are left to their parent-death checks)."""
        if self.p.poll() is None:
            self.p.kill()
            self.p.wait(60)
