"""The systemd unit ``docs/qsid-dashboard.service``: its stop leaves nothing behind.

There is no systemd here, so the test does what ``systemctl stop`` does with ``KillMode=mixed``: it runs the
unit's ExecStart command line (in a session of its own, as a control group would hold it), opens a tab so the
workers have work, sends SIGTERM to the main process only, and checks that the server exits with status 0 and
that no process it started is left (found by an environment tag, as systemd finds them by their cgroup) before
systemd's final SIGKILL of the group would come.
"""

from __future__ import annotations

import configparser
import os
import shlex
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from support import HANG_S, alive

# slow: runs the systemd unit's command line as a real process
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
UNIT = ROOT / "docs" / "qsid-dashboard.service"
sys.path.insert(0, str(ROOT / "benchmarks"))
from _wsclient import WsTab  # noqa: E402


def unit() -> configparser.ConfigParser:
    cp = configparser.ConfigParser(strict=False, interpolation=None)
    cp.optionxform = str
    cp.read(UNIT)
    return cp


def exec_start() -> list[str]:
    """ExecStart with the program run from this checkout, on loopback and a free port (tests never listen on
    other interfaces or fixed ports); every other option as the unit gives it."""
    argv = shlex.split(unit()["Service"]["ExecStart"])
    if argv[0].endswith("/env"):
        argv = argv[1:]
    assert argv[0] == "qsid-dashboard", argv
    args = argv[1:]
    for flag, value in (("--host", "127.0.0.1"), ("--port", "0")):
        args[args.index(flag) + 1] = value
    return [sys.executable, "-m", "app.dashboard", *args]


def tagged(tag: str) -> list[int]:
    out, needle = [], f"QSID_TEST_TAG={tag}".encode()
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/environ", "rb") as f:
                    if needle in f.read().split(b"\0") and alive(int(d)):
                        out.append(int(d))
            except OSError:
                pass
    return out


def test_the_unit_stops_by_sigterm_to_the_main_process_and_bounds_the_stop():
    svc = unit()["Service"]
    assert svc["KillMode"] in ("mixed", "control-group")  # leftovers are killed with the group
    assert svc.get("KillSignal", "SIGTERM") == "SIGTERM"
    assert 0 < float(svc["TimeoutStopSec"]) <= 90
    assert "--max-tabs" in svc["ExecStart"] and "--host" in svc["ExecStart"]


def test_stopping_the_units_command_like_systemd_leaves_no_process():
    tag = f"unit-{os.getpid()}"
    p = subprocess.Popen(
        exec_start(),
        cwd=ROOT,
        env=dict(os.environ, PYTHONPATH=str(ROOT), QSID_TEST_TAG=tag, PYTHONUNBUFFERED="1"),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    err: list[str] = []
    threading.Thread(target=lambda: err.extend(p.stderr), daemon=True).start()
    tab = None
    try:
        line, end = "", time.monotonic() + HANG_S
        while not line.startswith("qsid dashboard: http") and time.monotonic() < end and p.poll() is None:
            line = p.stdout.readline()
        assert line.startswith("qsid dashboard: http"), "".join(err)
        out: list[str] = []
        threading.Thread(target=lambda: out.extend(p.stdout), daemon=True).start()
        tab = WsTab(line.split()[2], timeout=HANG_S)
        tab.wait_ready(HANG_S)
        tab.send("realizations", 30)  # the workers are busy when the stop comes
        assert len(tagged(tag)) >= 3  # the server and its two workers
        p.send_signal(signal.SIGTERM)  # KillMode=mixed: SIGTERM to the main process only
        p.wait(HANG_S)
    finally:
        if tab is not None:
            tab.close()
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait(10)
    left, end = tagged(tag), time.monotonic() + 60  # a killed process may take a moment to vanish
    while left and time.monotonic() < end:
        time.sleep(0.2)
        left = tagged(tag)
    for pid in left:
        os.kill(pid, signal.SIGKILL)  # what systemd's final SIGKILL of the group would have had to do
    assert left == [], f"left for systemd to kill: {left}"
    assert p.returncode == 0 and "Traceback" not in "".join(err), (p.returncode, "".join(err)[-2000:])


def test_host_note_says_who_can_connect():
    from app.dashboard.options import who_can_connect

    note = who_can_connect("0.0.0.0", 8080)
    assert note.startswith("note: others connect at http://") and ":8080" in note and "no login" in note
    assert "\n" not in note  # one line
    assert who_can_connect("127.0.0.1", 8080) is None and who_can_connect("localhost", 8080) is None


def test_the_class_page_shows_the_note_line_the_server_prints():
    import re

    from app.dashboard.options import who_can_connect

    page = (ROOT / "docs" / "class.rst").read_text()
    shown = next(x.strip() for x in page.splitlines() if x.strip().startswith("qsid dashboard: note:"))
    printed = f"qsid dashboard: {who_can_connect('0.0.0.0', 8080)}"

    def mask(s):
        return re.sub(r"http://[^ ,]+:8080(, http://[^ ,]+:8080)*", "http://ADDRESS:8080", s)

    assert mask(shown) == mask(printed)
