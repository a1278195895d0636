"""The server's life from start to stop, around :class:`~app.dashboard.server.DashboardApp`.

* Start: :class:`StartupReport` prints each step as it begins (each line ``qsid dashboard: ...``, flushed), and a
  "still ..." line every :data:`TICK_SECONDS` while one takes long, so that a start that compiles the kernels
  (minutes on a busy machine) never looks hung; the engine reports its warm-up steps through a callback
  (:func:`qsid_core.studies.compile_kernels`). :func:`warm` compiles the kernels (or loads them from numba's disk
  cache, :func:`qsid_core.studies.kernel_cache_dir`) by a tiny computation through the same path a tab uses, in
  this process and then in every pool worker (which then only loads what this process wrote to the cache);
  :func:`prefill` and :func:`first_tab` then compute and draw a new tab's view once before the URL is printed:
  the first tab finds its results in the shared cache, plotly's figure code loaded (the first figures of a
  process took ~0.5 s more than later ones), and the page compressed by viser.
* Memory: the dashboard allocates and frees many mid-sized blocks from many threads (tabs' workers, viser's
  callback pool, the pool's result reader), and glibc's per-thread arenas keep what was freed: :func:`limit_arenas`
  caps their number before the threads start and :func:`trim` (``malloc_trim(0)``) returns free pages (both do
  nothing where glibc is not the allocator); :func:`trim_every` trims every :data:`TRIM_EVERY` seconds while the
  server runs, besides after each tab that closes. While tabs are open the server keeps their results and the pool
  workers the data of the last tasks; when no tab is left for :data:`IDLE_SECONDS`, :class:`IdleRelease` calls the
  server's release (clear the cache, fresh pool workers, trim) once. A tab that opens meanwhile cancels it; a
  reload (close, then open within seconds) therefore keeps every result. Once started, :func:`freeze_heap` puts
  what the start-up made beyond full collections' reach (they paused a class's burst of changes).
* Stop: Ctrl-C, SIGTERM and SIGHUP are taken on one path. :func:`prepare_stop_signals` is called before any thread
  exists; ``main`` then starts the server in a thread of its own, waits in :func:`wait_for_stop_signal` from the
  first moment of the start-up, and stops the app with :func:`stop_app`: the pool's workers are always killed and
  reaped, the web server is given :data:`STOP_WAIT` seconds. A stop during the start-up takes the same path (what
  exists so far is stopped).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import gc
import os
import signal
import sys
import threading
import time
import urllib.request
from collections.abc import Callable
from typing import Any, TextIO

from qsid_core.studies import compile_kernels, kernel_steps, kernels_cached
from qsid_core.studies import kernel_names as engine_kernel_names

__all__ = ["StartupReport", "TICK_SECONDS", "prepare_stop_signals", "wait_for_stop_signal", "stop_app", "STOP_WAIT"]
__all__ += ["RELEASE_WAIT", "IdleRelease", "IDLE_SECONDS", "limit_arenas", "trim", "trim_every", "TRIM_EVERY"]
__all__ += ["one_blas_thread", "needs_compiling", "kernel_names", "warm", "warm_here", "prefill", "fetch_page"]
__all__ += ["first_tab", "freeze_heap", "COMPILE_SECONDS", "COLD_START", "WARM_START"]


# ----- the start-up's report -----------------------------------------------------------------------------------
#: Seconds between two "still ..." lines while one step runs.
TICK_SECONDS = 5.0


class StartupReport:
    """Prints the start-up's steps and, while a step runs, a "still ..." line every ``tick`` seconds.

    Use as a context manager around the start-up (the ticker thread ends with it). :meth:`step` begins a step
    (``what``, and optionally ``k`` of ``n``); the ticker repeats it with the seconds the step and the whole
    start have taken so far.
    """

    def __init__(self, out: TextIO | None = None, tick: float = TICK_SECONDS):
        self.out = out if out is not None else sys.stdout
        self.tick = tick
        self._lock = threading.Lock()
        self._what = ""
        self._start = self._step_start = self._last = time.monotonic()
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._run, name="qsid-startup-report", daemon=True)

    def __enter__(self) -> StartupReport:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._done.set()
        self._thread.join(timeout=2 * self.tick)

    def say(self, text: str) -> None:
        """One line now (``qsid dashboard: text``), not repeated."""
        with self._lock:
            self._what = ""
            self._print(text)

    def _print(self, text: str) -> None:
        self._last = time.monotonic()
        print(f"qsid dashboard: {text}", file=self.out, flush=True)

    def step(self, what: str, k: int | None = None, n: int | None = None) -> None:
        """Step ``what`` begins (``k`` of ``n``, e.g. kernel 3 of 7), printed now and repeated while it runs."""
        with self._lock:
            self._what = f"{what} ({k} of {n})" if k is not None and n is not None else what
            self._step_start = time.monotonic()
            self._print(self._what)

    def _run(self) -> None:
        while not self._done.wait(self.tick / 5):
            with self._lock:
                now = time.monotonic()
                if self._what and now - self._last >= self.tick:
                    short = self._what.split(":")[0]  # "kernel 3 of 7: the box QP" -> "kernel 3 of 7"
                    self._print(
                        f"still {short}: {now - self._step_start:.0f} s so far, {now - self._start:.0f} s in all"
                    )

    @property
    def elapsed(self) -> float:
        """Seconds since the report began."""
        return time.monotonic() - self._start


# ----- warming up: the kernels and the first tab's view ----------------------------------------------------------
#: What the first compile of all kernels takes (measured: 15.1 s cold vs 1.0 s cached for this warm-up on a quiet
#: 2-CPU machine; rounded up for slower ones).
COMPILE_SECONDS = 20
#: How long a whole start takes, said when it begins (measured on the 2-core development machine: the first
#: start after an install 116 s and 2 min 24 s while other jobs ran; a later start 22 s to 70 s).
COLD_START = f"compiling the kernels once: ~{COMPILE_SECONDS} s on a quiet 2-core machine, 2 to 3 minutes on a busy one"
WARM_START = "starting: loading the compiled kernels and computing the first view, 20 s to about a minute"


def _presets() -> list:
    from qsid_core import PRESETS

    return [make() for make in PRESETS.values()]


def kernel_names() -> list[str]:
    """Every kernel :func:`warm_here` compiles, as numba names its cache index files (every preset's size)."""
    return engine_kernel_names(_presets())


def needs_compiling() -> bool:
    """True if some kernel has no machine code in numba's cache yet (the first run after an install)."""
    return not kernels_cached(_presets())


def warm_here(progress: Callable[[int, int, str], None] | None = None) -> int:
    """A tiny computation of a tab, saturated (so the compiled closed loop and the box-QP kernel run too), then
    every other kernel; returns this process's pid. ``progress(k, n, what)`` is told each of the ``n`` steps
    before it runs."""
    from app.frames.cache import SharedCache
    from app.frames.compute import iter_frames
    from app.settings.values import Values

    presets = _presets()
    n = 1 + len(kernel_steps(presets))
    if progress is not None:
        progress(1, n, "a tiny tab's computation (the closed loop, the box QP, the dc motor's quantizer)")
    v = Values(system="dc-motor", trajectories=4, steps=30, realizations=2, bits=4, mpc_steps=5, u_max=1e-3)
    for _ in iter_frames(v, SharedCache(16 * 2**20), None, 1):
        pass
    compile_kernels(presets, None if progress is None else lambda k, _n, what: progress(k + 1, n, what))
    return os.getpid()


def warm(pool, report: StartupReport | None = None) -> None:
    """Warm this process, then every worker of ``pool`` (a :class:`~app.dashboard.pool.Pool`); ``report`` is told
    each step."""
    warm_here(None if report is None else lambda k, n, what: report.step(f"kernel {k} of {n}: {what}"))
    ex = pool.current
    if ex is None:
        return
    if report is not None:
        report.step(
            "the worker process loads the kernels"
            if pool.workers == 1
            else f"the {pool.workers} worker processes load the kernels"
        )
    warmed: set[int] = set()
    while len(warmed) < pool.workers:  # until every worker ran it (each idle worker takes one of a round)
        warmed |= {f.result() for f in [ex.submit(warm_here) for _ in range(pool.workers)]}


def prefill(
    values, cache, executor=None, tasks: int = 1, progress: Callable[[Any], None] | None = None, figures=None
) -> int:
    """Compute the frames of a tab showing ``values`` into ``cache`` and build their figures once (``progress``
    is given each frame once drawn) into ``figures`` (the server's :class:`~app.frames.render.Figures`: a new
    tab on these settings then only pushes them).

    Returns the number of frames. Raises what the computation raises (e.g. a
    :class:`~qsid_core.errors.QsidError` for settings that cannot be computed).
    """
    from app.frames.compute import iter_frames
    from app.frames.render import Renderer

    renderer = Renderer(figures)  # (a linear plant, or a nonlinear one: --lesson koopman, a settings file of one)
    n = 0
    for frame in iter_frames(values, cache, executor, tasks):
        for wire in renderer.render(frame, values.axes).figures.values():  # (the 3-D axes as its panel shows them)
            wire.to_json()  # what viser calls when the figure is sent
        n += 1
        if progress is not None:
            progress(frame)
    return n


def fetch_page(host: str, port: int, timeout: float = 10.0) -> bool:
    """Request the dashboard's page once over loopback (viser compresses it on the first request);
    True if it answered."""
    host = {"0.0.0.0": "127.0.0.1", "::": "::1", "": "127.0.0.1"}.get(host, host)
    name = f"[{host}]" if ":" in host else host
    req = urllib.request.Request(f"http://{name}:{port}/", headers={"Accept-Encoding": "gzip"})
    opener = urllib.request.build_opener(urllib.request.ProxyHandler({}))  # loopback: never through a proxy
    try:
        with opener.open(req, timeout=timeout) as resp:
            resp.read()
            return resp.status == 200
    except OSError:
        return False


def first_tab(app, report: StartupReport | None = None) -> None:
    """Fetch the page once and compute + draw a new tab's view once, so the first tab is served like later ones
    (``report`` is told how far the view is)."""
    fetch_page(app.host, app.port)
    seen: list = []

    def drawn(frame) -> None:
        done, total = getattr(frame, "done", None), getattr(frame, "total", None)
        if report is not None and done is not None and total and done not in seen:
            seen.append(done)
            report.step(f"computing the first view: {done} of {total} word lengths drawn")

    if report is not None:
        report.step("computing the first view")
    why = app.prefill(drawn) if report is not None else app.prefill()
    if why:  # the server starts anyway
        print(f"qsid dashboard: the first view was not precomputed ({why})", flush=True)


# ----- memory: arenas, trimming, the release once idle --------------------------------------------------------
_M_ARENA_MAX = -8  # glibc's mallopt parameter number


def _libc():
    try:
        lib = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        lib.malloc_trim  # noqa: B018  (glibc only)
        return lib
    except (OSError, AttributeError):
        return None


_LIBC = _libc()


def limit_arenas(n: int = 2) -> bool:
    """At most ``n`` malloc arenas for threads started from now on; True if glibc took it."""
    return bool(_LIBC is not None and _LIBC.mallopt(_M_ARENA_MAX, int(n)))


def trim() -> bool:
    """Return the allocator's free pages to the system; True if any memory was released."""
    return bool(_LIBC is not None and _LIBC.malloc_trim(0))


#: Seconds between two :func:`trim` while the server runs.
TRIM_EVERY = 10.0


def trim_every(stop: threading.Event, seconds: float = TRIM_EVERY) -> None:
    """:func:`trim` every ``seconds`` in a daemon thread (``qsid-trim``) until ``stop`` is set."""

    def run() -> None:
        while not stop.wait(seconds):
            trim()

    threading.Thread(target=run, name="qsid-trim", daemon=True).start()


def freeze_heap() -> int:
    """Collect, then leave every object alive now to reference counting alone (:func:`gc.freeze`); returns how
    many. Once the server has started, its modules, plotly's validators, the lessons and the first view (~180,000
    objects) are never walked again by full collections, which paused a class's b changes 0.15-0.28 s each (what
    is frozen is still freed when its last reference goes; only a cycle among frozen objects would stay)."""
    gc.collect()
    gc.freeze()
    return gc.get_freeze_count()


def one_blas_thread() -> None:
    """Run BLAS with one thread in this whole process, from now on (the dashboard server and its workers).

    The engine's matrices are tiny and its parallelism comes from the tabs and the pool: extra BLAS threads
    only oversubscribe the cores. Set once, the engine's :func:`~qsid_core.studies.executors.single_threaded_blas`
    has nothing left to do on each call (it scanned every loaded library each time).
    """
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1, user_api="blas")  # not used as a context manager: the limit stays


#: Seconds without any tab before the server gives its memory back.
IDLE_SECONDS = 20.0


class IdleRelease:
    """Runs ``release()`` once, ``delay`` seconds after :meth:`schedule`, unless :meth:`cancel` came first.

    The timer runs in a daemon thread (``qsid-idle-release``), at most one at a time.
    """

    def __init__(self, release: Callable[[], None], delay: float = IDLE_SECONDS):
        self._release = release
        self.delay = float(delay)
        self._lock = threading.Lock()  # guards _timer: tabs open and close from viser's callback threads
        self._timer: threading.Timer | None = None
        self.releases = 0

    def schedule(self) -> None:
        """The last tab closed: release in ``delay`` seconds (a pending release starts over)."""
        with self._lock:
            if self._timer is not None:
                self._timer.cancel()
            self._timer = threading.Timer(self.delay, self._fire)
            self._timer.name = "qsid-idle-release"
            self._timer.daemon = True
            self._timer.start()

    def cancel(self) -> None:
        """A tab opened (or the server stops): no release."""
        with self._lock:
            if self._timer is not None:
                self._timer.cancel()
                self._timer = None

    @property
    def pending(self) -> bool:
        with self._lock:
            return self._timer is not None

    def _fire(self) -> None:
        with self._lock:
            if self._timer is None or threading.current_thread() is not self._timer:
                return  # cancelled or rescheduled meanwhile
            self._timer = None
        self.releases += 1
        self._release()


# ----- the stop ------------------------------------------------------------------------------------------------
_STOP_SIGNALS = {signal.SIGINT, signal.SIGTERM, signal.SIGHUP}


def prepare_stop_signals() -> threading.Event:
    """Route Ctrl-C, SIGTERM (kill, systemd, docker stop) and SIGHUP (terminal closed) to one stop path.

    Returns the event that is set when one of them arrives. Call before any thread exists.

    The three signals are blocked in this thread, so every thread started afterwards inherits the mask
    and they stay pending until :func:`wait_for_stop_signal` takes them with ``sigtimedwait`` (a library
    that swaps the SIGINT handler from a worker thread, as OSQP does on every solve, cannot swallow them).
    Python handlers are installed as well: if a thread unblocks them again, the signal delivered there
    still only sets the event instead of killing the process by the default action.
    """
    stop = threading.Event()

    def handler(signum, frame):
        stop.set()

    for sig in _STOP_SIGNALS:
        signal.signal(sig, handler)
    signal.pthread_sigmask(signal.SIG_BLOCK, _STOP_SIGNALS)
    return stop


def wait_for_stop_signal(stop: threading.Event) -> None:
    """Block until a stop signal is pending (taken here) or ``stop`` is set (by a handler, or by a thread that
    ends the wait, such as a failed start-up); ``stop`` is set on return, so every thread can tell."""
    while not stop.is_set():
        if signal.sigtimedwait(_STOP_SIGNALS, 0.1) is not None:
            break
    stop.set()


#: Seconds the stop waits for the pool's workers to be killed and reaped (they take milliseconds).
RELEASE_WAIT = 20.0
#: Seconds the stop gives the web server (and the tabs' workers) in all before the process leaves.
STOP_WAIT = 2.0


def _shutdown(app, released: threading.Event) -> None:
    app.halt()  # the tabs told to stop, the pool's workers killed and reaped
    released.set()
    app.server.stop()


def stop_app(app) -> None:
    """Stop ``app`` from the main thread: the pool always, the web server within ``STOP_WAIT``."""
    t0 = time.monotonic()
    released = threading.Event()
    stopper = threading.Thread(target=_shutdown, args=(app, released), name="qsid-stop", daemon=True)
    stopper.start()
    released.wait(RELEASE_WAIT)
    stopper.join(max(0.0, STOP_WAIT - (time.monotonic() - t0)))
