"""The dashboard server: one viser server, the tabs' shared cache and process pool, and ``main``.

Each browser tab gets its own controls, 3-D scene, plots and worker thread
(:class:`~app.dashboard.session.Session`, built in ``on_client_connect``). All
tabs share one bounded cache (:class:`~app.frames.cache.SharedCache`), one
small process pool for the heavy work, and a few compute slots, so many tabs
cannot exhaust the machine. Threading is described in :mod:`app.dashboard.session`.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import gc
import io
import os
import sys
import threading
import time
import traceback
from collections import OrderedDict

import viser

from app.frames.cache import DEFAULT_MB, SharedCache
from app.frames.render import Figures
from app.lessons.table import lesson_values
from app.settings.values import INTERACTIVE, PAPER_SCALE, Values, resolve_system
from app.settings.viewcodes import ViewStore, default_store_path, open_view, page_location
from qsid_core import ConfigError, QsidError

from .controls import panel_form
from .flow import READ_BYTES, FairSlots
from .follow import FollowHub
from .lifecycle import (
    COLD_START,
    WARM_START,
    IdleRelease,
    StartupReport,
    first_tab,
    freeze_heap,
    limit_arenas,
    needs_compiling,
    one_blas_thread,
    prefill,
    prepare_stop_signals,
    stop_app,
    trim,
    trim_every,
    wait_for_stop_signal,
    warm,
)
from .options import STARTING_SYSTEMS, check_lesson, check_options, parser, who_can_connect
from .pool import DEFAULT_TIMEOUT, Pool
from .scene import VIEW_FROM
from .session import Session
from .tabview import drop_late_draws
from .viserfix import connection_request, limit_reads, redirect_pages, refuse_share_requests, thread_safe_buffers

__all__ = ["DashboardApp", "main"]


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
    task_timeout : float
        Seconds one pool task may run before its worker counts as hung and is replaced.
    max_tabs : int, optional
        Tabs served at once; a further tab gets a page saying the dashboard is full (None: no limit).
    presenter : bool
        New tabs open in presenter mode (large text, a wide 3-D scene, auto-play).
    views_file : path, optional
        The JSON file that keeps the view codes' settings across restarts (None: in memory only).
    exact_port : bool
        Refuse (:class:`~qsid_core.errors.ConfigError`) to serve on another port than a non-zero ``port`` (viser
        moves to the next one when ``port`` is taken); False: the next one is fine (``--next-free-port``).
    """

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = 8080,
        system: str = "dc-motor",
        workers: int = 2,
        slots: int = 2,
        scale: str = "interactive",
        verbose: bool = False,
        cache_bytes: int = DEFAULT_MB * 2**20,
        settings: Values | None = None,
        lesson: str | None = None,
        task_timeout: float = DEFAULT_TIMEOUT,
        max_tabs: int | None = None,
        presenter: bool = False,
        views_file=None,
        exact_port: bool = True,
    ):
        if system not in STARTING_SYSTEMS:
            raise QsidError(f"unknown system {system!r}; use one of {', '.join(STARTING_SYSTEMS)}")
        size = PAPER_SCALE if scale == "paper" else INTERACTIVE
        self.defaults = settings if settings is not None else Values(system=system).replace(**size)
        if lesson is not None:  # every new tab opens on the lesson (its settings, its text)
            self.defaults = lesson_values(check_lesson(lesson), self.defaults)
        if presenter:
            self.defaults = self.defaults.replace(presenter=True)
        drop_late_draws()  # a draw that a closing tab cuts short is dropped without a warning
        self.views = ViewStore(views_file)  # view codes -> settings (links that survive a reload)
        self.follow = FollowHub(self.views, self._code_in_use)  # tabs followed live by other tabs
        self.cache = SharedCache(cache_bytes)
        self.figures = Figures()  # every figure drawn, made once for all tabs drawing it (:class:`Figures`)
        self.slots = FairSlots(slots, fast=1)  # (4) at most `slots` tabs compute at once, in turn; cheap turns first
        self.workers = max(0, int(workers))
        self.tasks = max(1, self.workers)
        self._lock = threading.Lock()  # (5) guards `sessions` and `_gone`
        self.idle = IdleRelease(self._release_memory)  # (10) memory back once no tab is left for a while
        self.sessions: dict[int, Session] = {}
        self.max_tabs = max_tabs
        self._admitted: set = set()  # client ids holding one of the max_tabs places (built or being built)
        self._gone: OrderedDict = OrderedDict()  # client ids that closed before their tab was built
        # viser prints its own box with the URL as soon as its port opens, before the warm-up: the one URL a
        # person sees is qsid's ready line (printed by main once a tab is served at once), so the box goes
        # nowhere (rich writes to sys.stdout at print time; only this constructor's output is redirected)
        with contextlib.redirect_stdout(io.StringIO()):
            self.server = viser.ViserServer(host=host, port=port, verbose=verbose)
        if exact_port and port != 0 and self.server.get_port() != port:  # viser took the next port: not asked for
            moved = self.server.get_port()
            self.server.stop()
            raise ConfigError(
                f"--port {port} on {host} was taken by another program while the dashboard started (it would have "
                f"moved to {moved}); start again, choose another --port, or add --next-free-port"
            )
        thread_safe_buffers(self.server)  # before any tab: every message buffer can be pushed to from any thread
        self.pool = Pool(self.workers, task_timeout)  # (7) the process pool and its watchdog (after the port)
        self._halted = threading.Event()
        trim_every(self._halted)  # (10) this process's freed memory back to the system, until halted
        self.server.gui.configure_theme(show_share_button=False, show_logo=False)
        self.server.gui.set_panel_label("qsid dashboard")
        cam = self.server.initial_camera  # every new tab starts looking at the unit box from here
        cam.position = VIEW_FROM
        cam.look_at = (0.0, 0.0, 0.0)
        cam.up = (0.0, 0.0, 1.0)
        refuse_share_requests(self.server)
        connection_request(self.server, -1)  # view links need the websocket's path: fail now, not silently later
        #: page requests redirected to addresses that hold a view code (else: long links, no code in the address)
        self.redirecting = redirect_pages(self.server, self._page_location)
        self.server.on_client_connect(self._connect)
        self.server.on_client_disconnect(self._disconnect)

    @property
    def executor(self):
        """The process pool now in use (None: in-process)."""
        return self.pool.current

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
        self.idle.cancel()
        limit_reads(self.server, client.client_id, READ_BYTES)  # a flooding tab cannot make the event loop's turns long
        with self._lock:
            full = self.max_tabs is not None and len(self._admitted) >= self.max_tabs
            if not full:
                self._admitted.add(client.client_id)
        if full:
            client.gui.add_markdown(
                f"**This dashboard is full**: it serves at most {self.max_tabs} tab(s) at a "
                "time, so that every open tab stays fast. Close another tab, or reload this "
                "page in a while."
            )
            return
        try:
            path, host = connection_request(self.server, client.client_id) or ("/", "")
            values, view = open_view(
                self.views, path, host or f"{self.host}:{self.port}", self.defaults, in_use=self._code_in_use
            )
            s = Session(self, client, values, dataclasses.replace(view, short=self.redirecting))
        except Exception:  # a broken tab must not take the server down
            traceback.print_exc()
            with self._lock:
                self._admitted.discard(client.client_id)
            return
        with self._lock:
            gone = self._gone.pop(client.client_id, None) is not None
            if not gone:
                self.sessions[client.client_id] = s
            else:
                self._admitted.discard(client.client_id)
        if gone:  # the tab closed while it was being built (seconds on a busy server): nobody would close it
            self.follow.detach(s)
            s.close(wait=False)
            trim()

    def _disconnect(self, client) -> None:
        with self._lock:
            s = self.sessions.pop(client.client_id, None)
            self._admitted.discard(client.client_id)
            if s is None:  # still being built by _connect (both run in viser's thread pool, in any order)
                self._gone[client.client_id] = True
                while len(self._gone) > 4096:  # ids whose _connect never came (bounded)
                    self._gone.popitem(last=False)
        if s is not None:
            self.follow.detach(s)  # a follower leaves; a leader's followers keep its last view
            s.close(wait=False)  # never block viser's callback threads; the worker ends at its next check
            self.views.flush()
            trim()
        with self._lock:
            idle = not self.sessions and not self._admitted
        if idle:
            self.idle.schedule()

    def prefill(self, progress=None) -> str | None:
        """Compute and draw a new tab's view once (see :func:`.lifecycle.prefill`; ``progress`` is given each frame);
        returns why not, or None."""
        try:  # the settings as a new tab's panel reads them (texts, x0, weights filled in): its very results
            values = panel_form(self.defaults, resolve_system(self.defaults).system)
            prefill(values, self.cache, self.executor, self.tasks, progress, self.figures)
        except Exception as exc:  # the tab itself reports what these settings raise
            return str(exc) if isinstance(exc, QsidError) else f"{type(exc).__name__}: {exc}"
        return None

    def _release_memory(self) -> None:
        """No tab for a while: the results, the workers' data and free pages go back to the system; the
        default view is computed again, so the next first tab is as quick as the first one was."""
        with self._lock:
            if self.sessions or self._admitted:
                return
        self.cache.clear()
        self.figures.clear()
        self.pool.release()
        gc.collect()
        trim()
        self.prefill()

    def _page_location(self, target: str, host: str, secure: bool) -> str | None:
        """Where a page request is redirected (:func:`~app.settings.viewcodes.page_location`), or None."""
        return page_location(target, host, secure, self.views.new_code)

    def _code_in_use(self, code: str, but=None) -> bool:
        """True while an open tab (other than session ``but``) shows view code ``code``."""
        with self._lock:
            codes = [s.codes for s in self.sessions.values() if s is not but]
        return any(c is not None and c.view.code == code for c in codes)

    def wait_for_sessions(self, count: int, timeout: float = 30.0) -> list:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with self._lock:
                if len(self.sessions) >= count:
                    return list(self.sessions.values())
            time.sleep(0.05)
        raise TimeoutError(f"{count} browser tab(s) did not connect within {timeout} s")

    def halt(self) -> list:
        """Tell every tab to stop, kill the pool and save the view codes; the web server keeps running.

        Returns the closed sessions (their workers may still be finishing).
        """
        self.idle.cancel()
        self._halted.set()
        with self._lock:
            sessions = list(self.sessions.values())
            self.sessions.clear()
        for s in sessions:
            s.close(wait=False)
        self.pool.shutdown()  # workers killed: a tab's pending task fails at once
        self.views.flush()
        return sessions

    def stop(self, wait: bool = True) -> None:
        """Close every tab, the server and the pool (``wait=False``: do not wait for the tabs' workers)."""
        sessions = self.halt()
        if wait:
            for s in sessions:
                s.close()
        self.server.stop()


class _Start:
    """What the start-up thread has made so far (``app`` once built) and how it ended (``failed``: the error line)."""

    def __init__(self) -> None:
        self.app: DashboardApp | None = None
        self.report: StartupReport | None = None  # the start-up's progress lines (ended by a stop)
        self.failed: str | None = None
        self.ready = False


def _start(args: argparse.Namespace, state: _Start, stop: threading.Event) -> None:
    """(the start-up thread) Check the options, the port first; start the server; warm it up; print its URL once a
    tab is served at once. A failure is kept in ``state`` and ends the wait of ``main`` (``stop`` set)."""
    try:
        settings, warning = check_options(args)
        if warning:
            print(f"qsid-dashboard: {warning}", file=sys.stderr, flush=True)
        with StartupReport() as report:  # a line per step, and every few seconds while one takes long
            state.report = report
            report.say(COLD_START if needs_compiling() else WARM_START)
            report.step(
                f"starting the server and {args.workers} worker process{'es' * (args.workers > 1)}"
                if args.workers
                else "starting the server"
            )
            state.app = app = DashboardApp(
                args.host,
                args.port,
                args.system,
                workers=args.workers,
                scale=args.scale,
                settings=settings,
                lesson=args.lesson,
                task_timeout=args.task_timeout,
                cache_bytes=args.cache_mb * 2**20,
                max_tabs=args.max_tabs,
                presenter=args.presenter,
                views_file=default_store_path(),
                exact_port=not args.next_free_port,
            )
            if app.views.load_note:
                print(f"qsid-dashboard: {app.views.load_note}", file=sys.stderr, flush=True)
            warm(app.pool, report)  # the first tab must not pay the compiler (nor the workers' first loads)
            first_tab(app, report)
            freeze_heap()  # what the start-up made stays out of every later full collection
        print(f"qsid dashboard: {app.url}   ({_port_note(args, app.port)}Ctrl-C to stop)", flush=True)
        note = who_can_connect(args.host, app.port)
        if note:
            print(f"qsid dashboard: {note}", flush=True)
        state.ready = True
    except BaseException as exc:
        if stop.is_set():  # stopped meanwhile (a signal): what failed is the stop's doing, not news
            return
        if not isinstance(exc, (QsidError, OSError)):  # an internal error: its traceback; the start ends all the same
            traceback.print_exc()
        state.failed = str(exc) if isinstance(exc, (QsidError, OSError)) else f"internal error ({type(exc).__name__})"
        stop.set()


def _port_note(args: argparse.Namespace, port: int) -> str:
    """What the URL line says of a port other than the one asked for (``--port 0``, ``--next-free-port``)."""
    if args.asked_port == 0:
        return f"--port 0: port {port}, a free one the system chose; "
    if port != args.asked_port:
        return f"port {args.asked_port} was in use: --next-free-port took {port}; "
    return ""


def _serve(args: argparse.Namespace, stop: threading.Event) -> int:
    """Start the server in a thread of its own and wait for a stop signal from the first moment: Ctrl-C, SIGTERM
    and SIGHUP end the start-up at any point of it (the port check, the kernels' compilation, the workers' start,
    the first view) as they end the server. Returns the exit status (2: it could not start)."""
    state = _Start()
    starter = threading.Thread(target=_start, args=(args, state, stop), name="qsid-start", daemon=True)
    starter.start()
    wait_for_stop_signal(stop)
    if state.report is not None and not state.ready:
        state.report.__exit__(None, None, None)  # no "still ..." line after this
    if state.failed is not None:
        print(f"qsid-dashboard: error: {state.failed}", file=sys.stderr, flush=True)
    else:
        print(f"\nqsid dashboard: stopping{'' if state.ready else ' (before it was ready)'}", flush=True)
    if state.app is not None:  # stop within ~2 s whatever the tabs are computing, then leave at once
        stop_app(state.app)
    return 2 if state.failed is not None else 0


def main(argv: list[str] | None = None) -> int:
    """Run the dashboard until Ctrl-C / SIGTERM / SIGHUP (exit status 0); exit status 2 for bad options or a port
    that cannot be bound. Only parsing happens before the stop signals are taken: everything that can wait
    (the host's name, the port, the files, the server) runs in the start-up thread."""
    args = parser().parse_args(argv)  # --help, --version and malformed options: argparse's exit
    stop = prepare_stop_signals()  # before any thread exists: all inherit the mask
    limit_arenas(2)  # many threads, mid-sized blocks: per-thread arenas only hoard freed memory
    one_blas_thread()
    code = _serve(args, stop)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)  # tab workers and numerics threads are not waited for (nothing is left to save)
