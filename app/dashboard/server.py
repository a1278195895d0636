"""The dashboard server: one viser server, the tabs' shared cache and process pool, and ``main``.

Each browser tab gets its own controls, 3-D scene, plots and worker thread
(:class:`~app.dashboard.session.Session`, built in ``on_client_connect``). All
tabs share one bounded cache (:class:`~app.dashboard.cache.SharedCache`), one
small process pool for the heavy work, and a few compute slots, so many tabs
cannot exhaust the machine. Threading is described in :mod:`app.dashboard.session`.
"""

from __future__ import annotations

import argparse
import multiprocessing
import signal
import sys
import threading
import time
import traceback
from concurrent.futures import ProcessPoolExecutor

import viser

from qsid_core.errors import QsidError

from .cache import SharedCache
from .lessons import get_lesson, lesson_names, lesson_values
from .session import Session
from .settings import INTERACTIVE, PAPER_SCALE, SYSTEM_CHOICES, Values
from .share import load_settings_file

__all__ = ["DashboardApp", "main", "STARTING_SYSTEMS"]

#: Systems a tab can start with (the panel's presets; 'custom' is typed in the panel).
STARTING_SYSTEMS = tuple(x for x in SYSTEM_CHOICES if x != "custom")


def _ignore_sigint() -> None:  # pool workers: Ctrl-C is handled by the server process
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class DashboardApp:
    """The viser server plus everything the tabs share.

    Parameters
    ----------
    host, port : where to listen (``port=0``: any free port; see :attr:`port`).
    system : initial system of every new tab.
    workers : int
        Processes of the shared pool for the quantization work (0 = in-process).
    slots : int
        How many tabs may compute at the same time.
    scale : {"interactive", "paper"}
        Initial data size of new tabs.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 8080, system: str = "dc-motor", workers: int = 2,
                 slots: int = 2, scale: str = "interactive", verbose: bool = False,
                 cache_bytes: int = 512 * 2**20, settings: Values | None = None, lesson: str | None = None):
        if system not in STARTING_SYSTEMS:
            raise QsidError(f"unknown system {system!r}; use one of {', '.join(STARTING_SYSTEMS)}")
        size = PAPER_SCALE if scale == "paper" else INTERACTIVE
        self.defaults = settings if settings is not None else Values(system=system, **size)
        if lesson is not None:  # every new tab opens on the lesson (its settings, its text)
            self.defaults = lesson_values(_check_lesson(lesson), self.defaults)
        self.cache = SharedCache(cache_bytes)
        self.slots = threading.BoundedSemaphore(max(1, slots))  # (4) at most `slots` tabs compute at once
        self.workers = max(0, int(workers))
        self.tasks = max(1, self.workers)
        self._lock = threading.Lock()  # (5) guards `sessions` and the swap of `executor`
        self.executor = self._new_executor()  # (7) the process pool (None: in-process)
        self.sessions: dict[int, Session] = {}
        self.server = viser.ViserServer(host=host, port=port, verbose=verbose)
        self.server.gui.configure_theme(show_share_button=False, show_logo=False)
        self.server.gui.set_panel_label("qsid dashboard")
        cam = self.server.initial_camera  # every new tab starts looking at the unit box from here
        cam.position = (1.7, -2.2, 1.4)
        cam.look_at = (0.0, 0.0, 0.0)
        cam.up = (0.0, 0.0, 1.0)
        self.server.on_client_connect(self._connect)
        self.server.on_client_disconnect(self._disconnect)

    def _new_executor(self):
        if self.workers == 0:
            return None
        pool = ProcessPoolExecutor(self.workers, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_ignore_sigint)
        try:
            for f in [pool.submit(abs, 0) for _ in range(self.workers)]:  # start the workers now
                f.result()
        except Exception as exc:  # e.g. started from a script without a __main__ guard
            pool.shutdown(wait=False, cancel_futures=True)
            print(f"qsid-dashboard: no worker processes ({type(exc).__name__}: {exc}); computing in-process",
                  file=sys.stderr)
            return None
        return pool

    def reset_executor(self) -> None:
        with self._lock:
            old, self.executor = self.executor, self._new_executor()
        if old is not None:
            old.shutdown(wait=False, cancel_futures=True)

    @property
    def host(self) -> str:
        return self.server.get_host()

    @property
    def port(self) -> int:
        return self.server.get_port()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    def _connect(self, client) -> None:
        try:
            s = Session(self, client, self.defaults)
        except Exception:  # a broken tab must not take the server down
            traceback.print_exc()
            return
        with self._lock:
            self.sessions[client.client_id] = s

    def _disconnect(self, client) -> None:
        with self._lock:
            s = self.sessions.pop(client.client_id, None)
        if s is not None:
            s.close()

    def wait_for_sessions(self, count: int, timeout: float = 30.0) -> list:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with self._lock:
                if len(self.sessions) >= count:
                    return list(self.sessions.values())
            time.sleep(0.05)
        raise TimeoutError(f"{count} browser tab(s) did not connect within {timeout} s")

    def stop(self) -> None:
        with self._lock:
            sessions = list(self.sessions.values())
            self.sessions.clear()
        for s in sessions:
            s.close()
        self.server.stop()
        if self.executor is not None:
            self.executor.shutdown(wait=True, cancel_futures=True)


def _check_lesson(name: str) -> str:
    try:
        get_lesson(name)
    except KeyError as exc:
        raise QsidError(exc.args[0]) from None
    return name


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="qsid-dashboard", description="Live dashboard: quantized data -> "
                                "identification -> MPC. Open the printed URL in a browser.")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=int, default=8080, help="port (default 8080; the next free one if taken)")
    p.add_argument("--system", default="dc-motor", choices=STARTING_SYSTEMS, help="initial system of new tabs")
    p.add_argument("--scale", default="interactive", choices=("interactive", "paper"),
                   help=f"initial data size: interactive ({INTERACTIVE['trajectories']} x {INTERACTIVE['steps']}, "
                        f"{INTERACTIVE['realizations']} realizations) or paper ({PAPER_SCALE['trajectories']} x "
                        f"{PAPER_SCALE['steps']}, {PAPER_SCALE['realizations']})")
    p.add_argument("--workers", type=int, default=2,
                   help="processes for the quantization and closed-loop work, shared by all tabs "
                        "(0 = in-process; default 2)")
    p.add_argument("--settings", metavar="FILE", default=None,
                   help="start every new tab from a settings file (saved with the panel's 'Download settings')")
    p.add_argument("--lesson", default=None, metavar="NAME",
                   help=f"open new tabs on a lesson: {', '.join(lesson_names()[1:])}")
    return p


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if args.lesson is not None:
        try:
            _check_lesson(args.lesson)
        except QsidError as exc:
            print(f"qsid-dashboard: error: {exc}", file=sys.stderr)
            return 2

    def _term(_sig, _frm):
        raise KeyboardInterrupt

    app = None
    try:
        signal.signal(signal.SIGINT, signal.default_int_handler)  # also when started with SIGINT ignored
        signal.signal(signal.SIGTERM, _term)
        settings = None if args.settings is None else load_settings_file(args.settings)
        app = DashboardApp(args.host, args.port, args.system, workers=args.workers, scale=args.scale,
                           settings=settings, lesson=args.lesson)
        print(f"qsid dashboard: {app.url}   (Ctrl-C to stop)", flush=True)
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        print("\nqsid dashboard: stopping", flush=True)
    except (QsidError, OSError) as exc:
        print(f"qsid-dashboard: error: {exc}", file=sys.stderr)
        return 2
    finally:
        if app is not None:
            try:
                app.stop()
            except KeyboardInterrupt:
                pass
    return 0
