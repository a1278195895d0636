"""qsid-dashboard: the live viser dashboard (``qsid-dashboard [--host] [--port] [--system]``).

Each browser tab gets its own controls, 3-D scene and plots (built in
``server.on_client_connect`` with ``client.gui`` / ``client.scene``) and one
worker thread (:class:`Session`). viser runs input callbacks concurrently on a
thread pool, so callbacks only bump a generation counter; the worker reads the
newest values, asks the engine (:func:`app.dashboard_compute.iter_frames`),
and draws a frame only if no newer setting arrived meanwhile. All tabs share one
bounded cache (:class:`~app.dashboard_state.SharedCache`), one small process
pool for the heavy quantization work, and two compute slots, so many tabs
cannot exhaust the machine.
"""

from __future__ import annotations

import os
import sys

if "numpy" not in sys.modules:  # started as the program: many tiny matrices, BLAS threads only cost
    for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_var, "1")

import argparse
import multiprocessing
import signal
import threading
import time
import traceback
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

import viser

from qsid_core.errors import QsidError
from qsid_core.systems import PRESETS, get_system

from .dashboard_compute import Frame, Renderer, iter_frames
from .dashboard_gui import Controls
from .dashboard_scene import PhasePortrait
from .dashboard_state import INTERACTIVE, PAPER_SCALE, SYSTEM_CHOICES, SharedCache, Values, resolve_system

__all__ = ["DashboardApp", "Session", "main"]

#: Systems a tab can start with (the panel's presets; 'custom' is typed in the panel).
STARTING_SYSTEMS = tuple(x for x in SYSTEM_CHOICES if x != "custom")
PLOT_ASPECT = {"error": 0.62, "cost": 0.6, "bound": 0.6, "eigen": 0.75}


def _ignore_sigint() -> None:  # pool workers: Ctrl-C is handled by the server process
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class Session:
    """One browser tab: its controls, scene, plots and the worker thread that redraws them."""

    def __init__(self, app: "DashboardApp", client, values: Values):
        self.app = app
        self.client = client
        self._gen = 0
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._idle = threading.Condition(self._lock)
        self._finished_gen = -1
        self._closed = False
        self.frames_drawn = 0
        self.last_frame: Frame | None = None
        self.last_error: str | None = None
        self.timings: dict = {}
        gui = client.gui
        gui.configure_theme(show_share_button=False, control_width="large", show_logo=False)
        # place the panels before filling them: moving a filled panel re-mounts its plots
        gui.main_panel.dock_left()
        self.plots_panel = gui.add_panel()
        self.plots_panel.dock_right()
        self.plots_panel.set_width(440)
        system = get_system(values.system) if values.system in PRESETS else resolve_system(values).system
        self.controls = Controls(gui, values, system, self.touch)
        with self.plots_panel.add_tab("Plots"):
            self.plots = {name: gui.add_plotly(_blank(), aspect=PLOT_ASPECT[name]) for name in PLOT_ASPECT}
        self.renderer = Renderer()
        self.portrait = PhasePortrait(client.scene)
        self.thread = threading.Thread(target=self._loop, name=f"qsid-tab-{client.client_id}", daemon=True)
        self.thread.start()
        self.touch()

    # ----- called from viser's callback threads -----------------------------------------
    def touch(self) -> None:
        """Something changed: the worker recomputes from the newest values (older work is dropped)."""
        with self._lock:
            self._gen += 1
        self._wake.set()

    def close(self) -> None:
        self._closed = True
        self._wake.set()
        if threading.current_thread() is not self.thread:
            self.thread.join(timeout=10)

    def wait_idle(self, timeout: float = 60.0) -> bool:
        """Block until every change so far is fully drawn (for tests and benchmarks)."""
        end = time.monotonic() + timeout
        with self._idle:
            while self._finished_gen != self._gen:
                left = end - time.monotonic()
                if left <= 0:
                    return False
                self._idle.wait(left)
        return True

    @property
    def generation(self) -> int:
        return self._gen

    # ----- worker ----------------------------------------------------------------------------
    def _stale(self, gen: int) -> bool:
        return self._closed or self._gen != gen

    def _loop(self) -> None:
        while not self._closed:
            self._wake.wait(0.5)
            if self._closed:
                break
            if not self._wake.is_set():
                continue
            self._wake.clear()
            gen = self._gen
            try:
                self._run(gen)
            except Exception as exc:  # never let the worker die: show it, keep the last view
                traceback.print_exc()
                self._show_error(f"internal error ({type(exc).__name__}): {exc}")
            with self._idle:
                if gen == self._gen:
                    self._finished_gen = gen
                self._idle.notify_all()

    def _run(self, gen: int) -> None:
        c = self.controls
        values = c.values()
        c.show_weights()
        try:
            choice = resolve_system(values)
        except QsidError as exc:
            self._show_error(str(exc))
            return
        if c.set_system(choice.system):
            values = c.values()
        t0 = time.perf_counter()

        def progress(done: int, total: int, text: str) -> None:
            if not self._stale(gen):
                c.progress.value = 100.0 * done / total
                c.status.content = text

        frames = iter_frames(values, self.app.cache, self.app.executor, self.app.tasks,
                             should_stop=lambda: self._stale(gen), on_progress=progress)
        try:
            while True:
                with self.app.slots:  # at most a few tabs compute at once
                    if self._stale(gen):
                        return
                    frame = next(frames, None)
                if frame is None or self._stale(gen):
                    return
                if not self._draw(frame, gen):
                    return
                key = "current" if frame.stage == "current" else "all"
                self.timings[key] = time.perf_counter() - t0
                if frame.complete:
                    c.progress.value = 100.0
                    c.status.content = (f"ready · b = {frame.bits} drawn in {self.timings['current']:.2f} s, "
                                        f"all curves in {self.timings['all']:.2f} s")
        except QsidError as exc:
            self._show_error(str(exc))
        except BrokenProcessPool:
            self.app.reset_executor()
            self._show_error("the computation pool crashed and was restarted; change a setting to retry")

    def _show_error(self, text: str) -> None:
        self.last_error = text
        c = self.controls
        c.error.content = f"⚠️ **Cannot update:** {text}  \n*The view still shows the last good result.*"
        c.error.visible = True
        c.status.content = "error – see below"
        c.progress.value = 0.0

    def _draw(self, frame: Frame, gen: int) -> bool:
        """Push ``frame`` to the tab unless newer settings arrived meanwhile; True if drawn."""
        c = self.controls
        r = self.renderer.render(frame, c.axes.value)
        if self._stale(gen):  # never draw an older result over a newer one
            self.renderer = Renderer()  # it remembered figures that were not pushed
            return False
        with self.client.atomic():
            if c.error.visible:
                c.error.visible = False
                self.last_error = None
            if r.scene is not None:
                self.portrait.draw(r.scene)
            if r.summary is not None:
                c.summary.content = r.summary
            for name, fig in r.figures.items():
                self.plots[name].figure = fig
        self.last_frame = frame
        self.frames_drawn += 1
        return True


def _blank():
    import plotly.graph_objects as go

    fig = go.Figure()
    fig.update_layout(height=200, template="plotly_white", margin=dict(l=10, r=10, t=10, b=10),
                      annotations=[dict(text="computing …", showarrow=False, x=0.5, y=0.5, xref="paper",
                                        yref="paper")],
                      xaxis=dict(visible=False), yaxis=dict(visible=False))
    return fig


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
                 cache_bytes: int = 512 * 2**20):
        if system not in STARTING_SYSTEMS:
            raise QsidError(f"unknown system {system!r}; use one of {', '.join(STARTING_SYSTEMS)}")
        size = PAPER_SCALE if scale == "paper" else INTERACTIVE
        self.defaults = Values(system=system, **size)
        self.cache = SharedCache(cache_bytes)
        self.slots = threading.BoundedSemaphore(max(1, slots))
        self.workers = max(0, int(workers))
        self.tasks = max(1, self.workers)
        self._pool_lock = threading.Lock()
        self.executor = self._new_executor()
        self.sessions: dict[int, Session] = {}
        self._sessions_lock = threading.Lock()
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
        with self._pool_lock:
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
        with self._sessions_lock:
            self.sessions[client.client_id] = s

    def _disconnect(self, client) -> None:
        with self._sessions_lock:
            s = self.sessions.pop(client.client_id, None)
        if s is not None:
            s.close()

    def wait_for_sessions(self, count: int, timeout: float = 30.0) -> list:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with self._sessions_lock:
                if len(self.sessions) >= count:
                    return list(self.sessions.values())
            time.sleep(0.05)
        raise TimeoutError(f"{count} browser tab(s) did not connect within {timeout} s")

    def stop(self) -> None:
        with self._sessions_lock:
            sessions = list(self.sessions.values())
            self.sessions.clear()
        for s in sessions:
            s.close()
        self.server.stop()
        if self.executor is not None:
            self.executor.shutdown(wait=True, cancel_futures=True)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="qsid-dashboard", description="Live dashboard: quantized data -> "
                                "identification -> MPC. Open the printed URL in a browser.")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=int, default=8080, help="port (default 8080; the next free one if taken)")
    p.add_argument("--system", default="dc-motor", choices=STARTING_SYSTEMS, help="initial system of new tabs")
    p.add_argument("--scale", default="interactive", choices=("interactive", "paper"),
                   help="initial data size: interactive (50 x 200, 20 realizations) or paper (200 x 1000, 50)")
    p.add_argument("--workers", type=int, default=2,
                   help="processes for the quantization and closed-loop work, shared by all tabs "
                        "(0 = in-process; default 2)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)

    def _term(_sig, _frm):
        raise KeyboardInterrupt

    app = None
    try:
        signal.signal(signal.SIGINT, signal.default_int_handler)  # also when started with SIGINT ignored
        signal.signal(signal.SIGTERM, _term)
        app = DashboardApp(args.host, args.port, args.system, workers=args.workers, scale=args.scale)
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


if __name__ == "__main__":
    sys.exit(main())
