"""Helpers shared by several test modules (not a test module itself: pytest collects nothing here).

* :class:`Tab` and :func:`open_tab`: a websocket client of an in-process dashboard server plus the
  server-side session viser built for it (the ``dashboard`` and ``tab`` fixtures of ``conftest.py``
  use them);
* :func:`dask_cluster` and :func:`need_distributed`: a real dask scheduler and workers on 127.0.0.1;
* from ``benchmarks/_support.py`` (shared with the benchmarks, which must not need pytest): the camera
  message, the websocket connection, the process tree (:func:`descendants`, :func:`alive`, ...) and
  :class:`DashboardProcess`, the server as a child process;
* :func:`fuzz_call` and :func:`fuzz_no_nan`: an engine call watched for non-engine exceptions, hangs and
  unflagged NaN, counted per entry point (``QSID_FUZZ_REPORT``; benchmarks/fuzz_engine.py).

Every wait here is a liveness guard against a hang, never a speed claim: :data:`HANG_S` is minutes,
so a busy machine only makes a test slower, never red.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
import warnings
from collections import Counter, defaultdict
from contextlib import contextmanager
from pathlib import Path

import msgspec
import pytest

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT / "benchmarks") not in sys.path:  # the helpers the benchmarks share with the tests
    sys.path.insert(0, str(ROOT / "benchmarks"))
import _support  # noqa: E402
from _support import (  # noqa: E402,F401
    CAMERA,
    DashboardProcess,
    alive,
    children,
    descendants,
    gone_within,
    pool_workers,
)

#: Seconds any single wait may take before the test calls it a hang (not a speed target).
HANG_S = 300.0

#: A small data size: every view of a tab is drawn in well under a second on a quiet machine.
SMALL = dict(trajectories=10, steps=60, realizations=4)


def connect_ws(app, path: str = "", **kwargs):
    """A raw websocket to the in-process server ``app`` at ``path`` (e.g. ``/v/CODE``, what a link's
    ``?websocket=ws://host/v/CODE`` opens) speaking viser's protocol (nothing sent yet)."""
    return _support.connect_ws(app.url + path, **kwargs)


class Tab:
    """One browser tab: a websocket client that reads everything, and its server-side session.

    Parameters
    ----------
    app : app.dashboard.DashboardApp
        A running in-process server.
    path : str
        The websocket's path (``""``: the bare address; ``/v/CODE``, ``/f/CODE/SPARE``: a link's).
    camera : dict, optional
        The first camera message (default :data:`CAMERA`: a 1400 × 900 canvas, a laptop's).
    """

    def __init__(self, app, path: str = "", camera: dict | None = None):
        self.app = app
        before = set(app.sessions)
        self.ws = connect_ws(app, path)
        self.received = 0
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()
        self.ws.send(msgspec.msgpack.encode(camera or CAMERA))  # viser's first camera message: the canvas size
        sessions = app.wait_for_sessions(len(before) + 1, timeout=HANG_S)
        self.session = next(s for s in sessions if s.client.client_id not in before)
        self.controls = self.session.controls

    def _read(self) -> None:
        try:
            while True:
                self.ws.recv()
                self.received += 1
        except Exception:
            pass

    def set(self, **values) -> Tab:
        """Set inputs as a person would (each runs the input's callbacks), then wait until redrawn."""
        for name, value in values.items():
            self.controls[name].value = value
        return self.wait()

    def wait(self, timeout: float = HANG_S) -> Tab:
        """Wait until the tab has drawn its newest settings; ``timeout`` only guards against a hang."""
        assert self.session.wait_idle(timeout), f"the tab was not redrawn within {timeout:g} s (hung?)"
        return self

    @property
    def frame(self):
        return self.session.last_frame

    @property
    def error(self) -> str | None:
        """The error text shown in the panel (None if hidden)."""
        return self.controls.error.content if self.controls.error.visible else None

    @property
    def summary(self) -> str:
        return self.controls.summary.content

    def close(self) -> None:
        self.ws.close()


def open_tab(app) -> Tab:
    """A tab at a small data size, its first view drawn."""
    t = Tab(app)
    t.set(mpc_steps=15, **SMALL)
    return t.wait()


def marks(tab: Tab, name: str = "error") -> list:
    """Where the dotted current-b markers of a plot are."""
    return [sh.x0 for sh in tab.session.plots[name].figure.layout.shapes if sh.name == "current b"]


def wait_until(predicate, what: str, timeout: float = HANG_S, every: float = 0.02) -> None:
    """Poll ``predicate()`` until true; fail after ``timeout`` s (a hang guard, not a speed claim)."""
    end = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < end, f"{what}: not after {timeout:g} s (hung?)"
        time.sleep(every)


def need_distributed() -> None:
    """Skip without the ``distributed`` package; with QSID_REQUIRE_DISTRIBUTED=1 (CI) fail instead."""
    if os.environ.get("QSID_REQUIRE_DISTRIBUTED") == "1":
        import distributed  # noqa: F401 -- CI: must run, a missing package fails
    else:
        pytest.importorskip("distributed")


def kill_group(proc: subprocess.Popen) -> None:
    """Stop a process started in its own session, with its children (the nanny's worker)."""
    if proc.poll() is not None:
        return
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGTERM)
    try:
        proc.wait(30)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(30)


def _scheduler_address(sfile: Path) -> str | None:
    """The address in a dask scheduler file, or None while it is missing or half written."""
    try:
        return json.loads(sfile.read_text())["address"]
    except (OSError, ValueError, KeyError):
        return None


@contextlib.contextmanager
def dask_cluster(tmp: Path, workers: int = 2):
    """A scheduler and ``workers`` worker processes on 127.0.0.1; yields (address, workers, scheduler)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    procs: list[subprocess.Popen] = []

    def start(args, log):
        fh = open(tmp / log, "wb")
        p = subprocess.Popen(
            [sys.executable, "-m", "dask", *args],
            cwd=ROOT,
            env=env,
            stdout=fh,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        fh.close()
        procs.append(p)
        return p

    try:
        sfile = tmp / "scheduler.json"
        sched = start(
            ["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--scheduler-file", str(sfile)],
            "scheduler.log",
        )
        end = time.monotonic() + HANG_S
        while (address := _scheduler_address(sfile)) is None:  # the file may be half written at first
            assert sched.poll() is None, (tmp / "scheduler.log").read_text()
            assert time.monotonic() < end, "dask scheduler did not start (hung?)"
            time.sleep(0.1)
        assert address.startswith("tcp://127.0.0.1:")
        wprocs = [
            start(
                [
                    "worker",
                    address,
                    "--nthreads",
                    "1",
                    "--nworkers",
                    "1",
                    "--host",
                    "127.0.0.1",
                    "--no-dashboard",
                    "--name",
                    f"w{i}",
                    "--local-directory",
                    str(tmp / f"w{i}"),
                ],
                f"worker{i}.log",
            )
            for i in range(workers)
        ]
        from distributed import Client

        with Client(address, timeout=HANG_S, set_as_default=False) as c:
            c.wait_for_workers(workers, timeout=HANG_S)
        yield address, wprocs, sched
    finally:
        for p in reversed(procs):
            kill_group(p)


# ------------------------------------------------------------------------------------------------
# hostile plant files
# ------------------------------------------------------------------------------------------------

#: A list nested 1,000 deep (the parsers' recursion limit).
DEEP_LIST = "[" * 1000 + "1" + "]" * 1000


def hostile_plant_file(tmp: Path, case: str) -> tuple[Path, str]:
    """The hostile file of ``case`` in ``tmp``, and words its refusal holds."""
    p = tmp / case
    if case == "deep.json":
        p.write_text('{"A": ' + DEEP_LIST + ', "B": [[1]]}')
        return p, "nested too deeply"
    if case == "deep-field.json":  # a nonlinear plant's file, nested in a key of its own
        p.write_text('{"vector_field": "m:f", "n": ' + DEEP_LIST + "}")
        return p, "nested too deeply"
    if case == "deep.toml":
        p.write_text("A = " + DEEP_LIST + "\nB = [[1]]\n")
        return p, "nested too deeply"
    if case == "deep-tables.toml":
        p.write_text("A = " + "{a = " * 1000 + "1" + "}" * 1000 + "\n")
        return p, "nested too deeply"
    if case == "huge-int.json":
        p.write_text('{"A": [[' + "9" * 5000 + ']], "B": [[1]]}')
        return p, "too many digits"
    if case == "huge-int.toml":
        p.write_text("A = [[" + "9" * 5000 + "]]\nB = [[1]]\n")
        return p, "too many digits"
    if case == "huge-float.json":
        p.write_text('{"A": [[1e400]], "B": [[1]]}')
        return p, "finite"
    if case == "binary.json":
        p.write_bytes(bytes(range(256)) * 4)
        return p, "not UTF-8"
    if case == "fifo.json":
        os.mkfifo(p)
        return p, "named pipe (FIFO)"
    if case == "dir.toml":
        p.mkdir()
        return p, "is a directory"
    if case == "loop.json":
        p.symlink_to(tmp / "loop2.json")
        (tmp / "loop2.json").symlink_to(p)
        return p, "Too many levels of symbolic links"
    if case == "list.json":
        p.write_text("[1, 2]")
        return p, "table/object with keys A and B"
    if case == "device.json":
        p.symlink_to("/dev/zero")
        return p, "character device"
    raise AssertionError(case)


#: The cases of :func:`hostile_plant_file`.
HOSTILE_PLANT_FILES = [
    "deep.json",
    "deep-field.json",
    "deep.toml",
    "deep-tables.toml",
    "huge-int.json",
    "huge-int.toml",
    "huge-float.json",
    "binary.json",
    "fifo.json",
    "dir.toml",
    "loop.json",
    "list.json",
    "device.json",
]


# ------------------------------------------------------------------------------------------------
# fuzzing the engine's entry points
# ------------------------------------------------------------------------------------------------

#: Seconds one call may run before it counts as a hang (a liveness guard, not a speed claim).
FUZZ_HANG_S = 120.0

#: entry point -> outcome -> count, written to ``QSID_FUZZ_REPORT`` at the end of the session.
FUZZ_OUTCOMES: dict[str, Counter[str]] = defaultdict(Counter)


class Hang(Exception):
    """A call ran past :data:`FUZZ_HANG_S`."""


@contextmanager
def _watch(seconds: float):
    def alarm(signum, frame):
        raise Hang(f"no answer within {seconds:.0f} s")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def fuzz_call(name, fn, *a, **k):
    """Run ``fn``: its result, or None for a QsidError with a message; anything else fails the test."""
    from qsid_core.errors import QsidError

    with warnings.catch_warnings(), _watch(FUZZ_HANG_S):
        warnings.simplefilter("ignore")
        try:
            out = fn(*a, **k)
        except QsidError as exc:
            FUZZ_OUTCOMES[name]["engine error"] += 1
            assert str(exc).strip(), "an engine error must say what is wrong"
            return None
        except Hang:
            FUZZ_OUTCOMES[name]["hang"] += 1
            raise
        except Exception:
            FUZZ_OUTCOMES[name]["other exception"] += 1
            raise
    FUZZ_OUTCOMES[name]["result"] += 1
    return out


def fuzz_no_nan(name, *arrays, flagged=None):
    """Every number finite where not ``flagged`` (a boolean mask of rows flagged as failed)."""
    import numpy as np

    for a in arrays:
        a = np.asarray(a, dtype=float)
        if flagged is not None:
            a = a[~np.asarray(flagged)]
        if not np.all(np.isfinite(a)):
            FUZZ_OUTCOMES[name]["unflagged NaN"] += 1
            raise AssertionError(f"{name}: a non-finite number that is not flagged")


def write_fuzz_report(path: str) -> None:
    """Add :data:`FUZZ_OUTCOMES` to the JSON counts in ``path`` (``QSID_FUZZ_REPORT``; see benchmarks/fuzz_engine.py)."""
    old = json.loads(Path(path).read_text()) if Path(path).exists() else {}
    for k, c in FUZZ_OUTCOMES.items():
        old[k] = dict(Counter(old.get(k, {})) + c)
    Path(path).write_text(json.dumps(old, indent=1, sort_keys=True))
