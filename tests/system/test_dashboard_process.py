"""The dashboard as a program: bad --port/--host, the beyond-loopback warning, Ctrl-C during heavy work.

The server runs as ``python -m app.dashboard`` (cwd = repo root); tabs are plain
websocket clients (:mod:`benchmarks._wsclient`) that send what a browser would.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from functools import partial
from pathlib import Path

import pytest
from support import HANG_S, DashboardProcess, alive, children, descendants, gone_within, wait_until

# slow: starts qsid-dashboard as a real process
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _wsclient import WsTab  # noqa: E402

ENV = dict(os.environ, PYTHONPATH=str(ROOT))


def run(*args, timeout=HANG_S):
    return subprocess.run(
        [sys.executable, "-m", "app.dashboard", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env=ENV,
        timeout=timeout,
    )


def dashboard_process(*args) -> subprocess.Popen:
    """``python -m app.dashboard --port 0 ARGS`` with its output readable as text."""
    return subprocess.Popen(
        [sys.executable, "-m", "app.dashboard", "--port", "0", *args],
        cwd=ROOT,
        env=ENV,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


#: ``python -m app.dashboard`` on a free loopback port; ``url`` once it printed it.
Server = partial(DashboardProcess, env=ENV, timeout=HANG_S)


@pytest.mark.parametrize("port", ["70000", "-1", "http"])
def test_bad_port_is_one_line_and_exit_2(port):
    r = run("--port", port)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr and "--port" in r.stderr and r.stdout == ""
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_unresolvable_host_is_one_line_and_exit_2():
    r = run("--host", "no-such-host.invalid", "--port", "0")
    assert r.returncode == 2, r.stderr
    assert r.stderr.strip().splitlines() == [r.stderr.strip()] and "cannot be resolved" in r.stderr
    assert "Traceback" not in r.stderr


def test_a_host_that_is_not_this_machine_is_one_line_and_exit_2():
    r = run("--host", "192.0.2.1", "--port", "0")  # TEST-NET-1: never an address of this machine
    assert r.returncode == 2 and "not an address of this machine" in r.stderr and "Traceback" not in r.stderr


def test_listening_beyond_loopback_warns():
    s = Server("--host", "0.0.0.0", "--workers", "0")
    try:
        s.p.send_signal(signal.SIGINT)
        err = s.stderr(HANG_S)
    finally:
        s.kill()
    assert "anyone who can reach it on the network can use the dashboard" in err
    assert s.p.returncode == 0


HEAVY = {"realizations": 100, "trajectories": 400, "steps": 2000, "horizon": 50, "closed-loop steps": 300}


@pytest.mark.slow
def test_ctrl_c_stops_everything_during_concurrent_mpc_work():
    """Three tabs compute saturated settings with the process pool busy; SIGINT ends the server by itself
    (exit code 0, no traceback) and its pool workers with it. How soon is measured by
    ``benchmarks/bench_responsiveness.py`` (a busy machine must not turn that figure into a failure)."""
    s = Server("--workers", "2")
    tabs = []
    try:
        tabs = [WsTab(s.url, HANG_S) for _ in range(3)]
        for i, t in enumerate(tabs):
            t.wait_for("closed-loop steps", HANG_S)
            for label, value in HEAVY.items():
                t.send(label, value)
            t.send("word length b", 3 + i)
        time.sleep(4.0)  # everyone deep in quantization and closed loops
        wait_until(lambda: len(children(s.p.pid)) >= 2, "the pool's two workers started")
        workers = children(s.p.pid)
        assert not any(t.ready for t in tabs)  # still computing
        t0 = time.monotonic()
        s.p.send_signal(signal.SIGINT)
        s.p.wait(timeout=HANG_S)
        took = time.monotonic() - t0
        err = s.p.stderr.read()
    finally:
        for t in tabs:
            t.close()
        s.kill()
    print(f"stopped {took:.2f} s after SIGINT")
    assert s.p.returncode == 0 and "Traceback" not in err, err
    wait_until(lambda: not any(alive(w) for w in workers), "the pool workers ended with the server", every=0.05)


@pytest.mark.slow
@pytest.mark.parametrize(
    "sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT, signal.SIGKILL], ids=["TERM", "HUP", "INT", "KILL"]
)
def test_every_signal_leaves_no_descendant(sig):
    """A tab open, the pool running: after the signal nothing the server started lives
    on; TERM/HUP/INT take the graceful path (one 'stopping' line, exit 0), KILL leaves workers that end by
    themselves (parent-death signal / getppid check)."""
    s = Server("--workers", "2")
    tab = None
    try:
        tab = WsTab(s.url)
        tab.wait_ready(120)
        desc = descendants(s.p.pid)
        assert len(desc) >= 2, desc  # the two pool workers
        s.p.send_signal(sig)
        s.p.wait(timeout=60)
        out, err = s.stdout(10), s.stderr(10)
        left = gone_within(desc, 60)
    finally:
        if tab is not None:
            tab.close()
        s.kill()
        for pid in descendants(s.p.pid) if s.p.poll() is None else []:
            os.kill(pid, signal.SIGKILL)
    assert left == [], f"still running after {sig.name}: {left}"
    if sig == signal.SIGKILL:
        return
    assert s.p.returncode == 0, (s.p.returncode, err)
    assert out.count("stopping") == 1, out
    assert "Traceback" not in err and "leaked" not in err, err


def test_one_url_shown_and_only_once_the_page_answers():
    """viser's own URL box (printed as its port opens, before the warm-up) is not shown: the output holds one
    URL line, qsid's ready line, and the page answers at the moment it appears."""
    import re
    import urllib.request

    p = dashboard_process()
    try:
        before, line, end = [], "", time.time() + HANG_S
        while not re.search(r"\w+://", line) and time.time() < end and p.poll() is None:
            line = p.stdout.readline()
            before.append(line)
        assert line.startswith("qsid dashboard: http://"), before
        opener = urllib.request.build_opener(urllib.request.ProxyHandler({}))
        with opener.open(line.split()[2], timeout=5) as resp:  # asked at once: the server is ready
            assert resp.status == 200 and b"<html" in resp.read().lower()
        p.send_signal(signal.SIGTERM)
        out, err = p.communicate(timeout=HANG_S)
        lines = before + out.splitlines()
        assert [ln for ln in lines if re.search(r"\w+://", ln)] == [line], lines
        assert not any("Websocket" in ln or "╭" in ln for ln in lines), lines  # viser's box
        assert not re.search(r"\w+://", err), err
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(HANG_S)
