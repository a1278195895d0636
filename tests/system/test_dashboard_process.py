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
from support import HANG_S, DashboardProcess, alive, children, descendants, gone_within, pool_workers, wait_until

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


# ------------------------------------------------------------------------------------------------
# a start-up that always ends (issue 40)
# ------------------------------------------------------------------------------------------------


def _one_line_exit_2(r: subprocess.CompletedProcess, *words: str) -> None:
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert r.stdout == "" and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, (r.stdout, r.stderr)
    for w in words:
        assert w in r.stderr, r.stderr


def test_a_port_in_use_is_one_line_and_exit_2_not_the_next_port():
    import socket

    with socket.socket() as s:  # another program on the port
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        port = s.getsockname()[1]
        t0 = time.monotonic()
        r = run("--port", str(port), "--workers", "2")
        took = time.monotonic() - t0
    print(f"--port {port} in use: exit {r.returncode} after {took:.1f} s")
    _one_line_exit_2(r, f"--port {port} on 127.0.0.1 is in use by another program")


def _without_low_ports() -> list[str]:
    """A command prefix that runs a program without the right to bind ports below 1024."""
    import shutil

    if os.geteuid() != 0:
        return []  # a user has no such right anyway
    if shutil.which("setpriv") is None:
        pytest.skip("root without setpriv: cannot drop CAP_NET_BIND_SERVICE")
    return ["setpriv", "--bounding-set=-net_bind_service", "--inh-caps=-net_bind_service"]


def test_port_1_without_the_right_to_bind_it_is_one_line_and_no_process_is_left():
    if int(Path("/proc/sys/net/ipv4/ip_unprivileged_port_start").read_text()) <= 1:
        pytest.skip("this machine lets anyone bind port 1")
    t0 = time.monotonic()
    p = subprocess.Popen(
        [*_without_low_ports(), sys.executable, "-m", "app.dashboard", "--port", "1", "--workers", "2"],
        cwd=ROOT,
        env=ENV,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    out, err = p.communicate(timeout=HANG_S)  # was: no line, no end, deaf to Ctrl-C and SIGTERM
    print(f"--port 1 without the right: exit {p.returncode} after {time.monotonic() - t0:.1f} s")
    _one_line_exit_2(subprocess.CompletedProcess(p.args, p.returncode, out, err), "--port 1", "permission denied")
    assert descendants(p.pid) == []


def _starting(workers: int = 2) -> tuple[subprocess.Popen, list[str]]:
    """The dashboard starting on a free port (``--port 0``), its stdout lines collected as they come."""
    import threading

    p = dashboard_process("--workers", str(workers))
    lines: list[str] = []
    threading.Thread(target=lambda: lines.extend(p.stdout), daemon=True).start()
    return p, lines


def _pool_workers(pid: int) -> list[int]:
    """The children of ``pid`` that are pool workers (not a short-lived helper some import runs)."""
    return pool_workers(pid)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["INT", "TERM"])
def test_a_stop_signal_ends_the_start_up_while_the_workers_start(sig):
    """Signalled once its pool's workers exist (the workers starting, the kernels warming, the first view being
    computed), before the URL: it stops at once, says so, and leaves no process behind."""
    p, lines = _starting()
    try:
        wait_until(
            lambda: _pool_workers(p.pid) or p.poll() is not None, "the pool's workers started", HANG_S, every=0.01
        )
        assert p.poll() is None and not any("://" in ln for ln in lines), lines
        workers = descendants(p.pid)
        t0 = time.monotonic()
        p.send_signal(sig)
        p.wait(HANG_S)
        took = time.monotonic() - t0
        err = p.stderr.read()
    finally:
        if p.poll() is None:
            p.kill()
    print(f"{sig.name} while the workers start: exit {p.returncode} after {took:.2f} s")
    assert p.returncode == 0 and "Traceback" not in err, err
    wait_until(lambda: "".join(lines).count("stopping (before it was ready)") == 1, "the stop is said", 10)
    assert gone_within(workers, 60) == [], "workers left behind"


def _importing(pid: int) -> bool:
    """Process ``pid`` is in the program's own imports: numpy's extension is mapped. Python's own start-up (site and
    the .pth files of site-packages) is over by then; a Ctrl-C during it ends in CPython ("Fatal Python error:
    init_import_site", exit 1), before any of the program's code, as a fixed delay can hit on a busy machine."""
    try:
        with open(f"/proc/{pid}/maps") as f:
            return "numpy" in f.read()
    except OSError:
        return False


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["INT", "TERM"])
def test_a_stop_signal_during_the_imports_ends_it_without_a_traceback(sig):
    p, lines = _starting()
    try:
        wait_until(lambda: _importing(p.pid) or p.poll() is not None, "the imports begun", HANG_S, every=0.01)
        assert p.poll() is None and not lines, lines  # still importing: nothing printed yet
        t0 = time.monotonic()
        p.send_signal(sig)
        p.wait(HANG_S)
        took = time.monotonic() - t0
        err = p.stderr.read()
    finally:
        if p.poll() is None:
            p.kill()
    print(f"{sig.name} during the imports: exit {p.returncode} after {took:.2f} s")
    assert p.returncode in (0, -sig), (p.returncode, err)  # killed by the signal, as a terminal expects
    assert "Traceback" not in err and not any("://" in ln for ln in lines), err


def test_the_url_says_when_the_port_is_not_the_one_asked_for():
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        p = subprocess.Popen(
            [sys.executable, "-m", "app.dashboard", "--port", str(port), "--next-free-port", "--workers", "0"],
            cwd=ROOT,
            env=ENV,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            ready = ""
            while "://" not in ready and p.poll() is None:
                ready = p.stdout.readline()
        finally:
            p.send_signal(signal.SIGTERM)
            p.wait(HANG_S)
    moved = int(ready.split()[2].rsplit(":", 1)[1])
    assert moved > port and f"port {port} was in use: --next-free-port took {moved}" in ready, ready


def test_port_0_says_the_system_chose_it():
    p, lines = _starting(workers=0)
    try:
        wait_until(lambda: any("://" in ln for ln in lines) or p.poll() is not None, "the URL", HANG_S)
    finally:
        p.send_signal(signal.SIGTERM)
        p.wait(HANG_S)
    (url,) = [ln for ln in lines if "://" in ln]
    port = url.split()[2].rsplit(":", 1)[1]
    assert f"(--port 0: port {port}, a free one the system chose; Ctrl-C to stop)" in url, url
