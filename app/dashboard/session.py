"""ALL threading of a browser tab: its worker (:class:`Session`) and the frame generator (:func:`iter_frames`).

Concurrency in the dashboard, every mechanism in one list (each is commented where it lives):

1. ``Session._cond`` (one per tab): viser runs input callbacks on its own thread
   pool; a callback only bumps the tab's generation under this condition and
   wakes the worker; :meth:`Session.wait_idle` waits on it too.
2. ``Session.thread`` (one per tab): the only thread that reads the panel,
   computes and draws; it drops a computation as soon as a newer generation exists.
3. the helper thread of :func:`iter_frames` (one per computation): quantizes the
   next chunk of word lengths while the worker runs closed loops, and runs the
   second estimator's closed loops beside the first.
4. ``DashboardApp.slots`` (server): a semaphore, at most a few tabs compute at once.
5. ``DashboardApp._lock`` (server): the tab registry.
6. ``SharedCache._lock`` (cache): the shared cache is read and written by all of the above.
7. the process pool (:mod:`.pool`): ``Pool._lock`` guards its replacement (only of the failed executor);
   its watchdog abandons stale pool tasks and times out hung workers (the tab retries once).
8. signals (server ``main``): SIGINT/SIGTERM blocked in every thread, taken by ``sigwait`` in main.
9. ``DataLengthRunner.thread`` (:mod:`.background`, at most one per tab): the data-length study on
   demand, in-process; cancelled when the tab's generation changes (any new change).
"""

from __future__ import annotations

import dataclasses
import threading
import time
import traceback
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Callable, Iterator, MutableMapping

from qsid_core.errors import QsidError
from qsid_core.systems import PRESETS, get_system

from .background import DataLengthRunner
from .controls import apply_lesson, make_gui_elements, read_values, set_system, show_weights
from .frames import Frame, fill_rows, make_frame, start
from .inputs import check_panel, unusable
from .pool import PoolFailure, Superseded, twice_message
from .render import Renderer
from .scene import PhasePortrait
from .settings import ALL_BITS, InputError, Values, resolve_system
from .share import add_share_panel, apply_pending, show_frame
from .viewpanel import PANEL_WIDTH, ViewPanel

__all__ = ["Session", "iter_frames"]

CHEAP = 0.15  #: a chunk quantized faster than this (s) is cheap (cached or small): queue all the rest at once


class _Ahead:
    """Quantizes ``parts`` (``ex.moments``) in the helper thread, one expensive part ahead of the reader."""

    def __init__(self, helper: ThreadPoolExecutor, ex, parts: list, stop: Callable[[], bool]):
        self.helper, self.ex, self.parts, self.stop = helper, ex, parts, stop
        self.futures: list[Future] = []

    def _task(self, part) -> float | None:
        if self.stop():
            return None
        t = time.perf_counter()
        self.ex.moments(part)
        return time.perf_counter() - t  # seconds: decides whether the rest is queued at once

    def _submit_through(self, k: int) -> None:
        while len(self.futures) <= min(k, len(self.parts) - 1):
            self.futures.append(self.helper.submit(self._task, self.parts[len(self.futures)]))

    def wait(self, k: int) -> None:
        """Return once part ``k`` is quantized (re-raises the helper's error); part k + 1 starts meanwhile."""
        self._submit_through(k + 1)
        if self.futures[k].result() is None:  # the helper skipped it (stop() was true): compute here
            self.ex.moments(self.parts[k])
        costs = [f.result() for f in self.futures if f.done() and f.exception() is None]
        if all(c is not None and c <= CHEAP for c in costs):
            self._submit_through(len(self.parts) - 1)

    @property
    def finished(self) -> bool:
        """Every part is quantized (and cached)."""
        return len(self.futures) == len(self.parts) and all(f.done() for f in self.futures)


def _loops_all(helper: ThreadPoolExecutor, job, rows: dict, bits: list) -> None:
    """Closed loops at ``bits`` for every estimator: the second one's in the helper thread, side by side."""
    first, *others = job.estimators
    futs = [(e, helper.submit(job.ex.closed_loops_many, bits, e)) for e in others]
    fill_rows(job, rows, first, bits, job.ex.closed_loops_many(bits, first))
    for e, f in futs:
        fill_rows(job, rows, e, bits, f.result())


def iter_frames(values: Values, cache: MutableMapping | None = None, executor=None, tasks: int = 1,
                should_stop: Callable[[], bool] | None = None, chunk: int = len(ALL_BITS) - 1, min_interval: float = 0.3,
                on_progress: Callable[[int, int, str], None] | None = None) -> Iterator[Frame]:
    """Compute what a tab shows for ``values``: a "current" frame, then "curves" frames.

    Parameters
    ----------
    values : Values
    cache : mapping, optional
        Shared :class:`~app.dashboard.cache.SharedCache` (anything a change does not touch is reused).
    executor, tasks
        Passed to :class:`~qsid_core.experiment.Experiment` (e.g. the dashboard's process pool).
    should_stop : callable, optional
        Polled between chunks; True ends the iteration (newer settings arrived).
    chunk : int
        Word lengths quantized per pass over the data. Default: all the others in one pass (each pass
        draws the dither again; one pass instead of three cut a paper-scale data change's CPU time by
        ~30%, benchmarks/bench_dashboard.py); a newer change then waits for that pass.
    min_interval : float
        A "curves" frame is yielded when this many seconds passed since the last one, and at the end.
    on_progress : callable(done, total, text), optional
        Called before each chunk ("computing b=5..9 (6/16)").

    Raises
    ------
    qsid_core.errors.QsidError
        Bad settings, data overflow, ... in plain words.
    """
    stop = should_stop or (lambda: False)
    t0 = time.perf_counter()
    b, total = int(values.bits), len(ALL_BITS)
    if on_progress:
        on_progress(0, total, f"computing b={b} (1/{total})")
    job, rows = start(values, cache, executor, tasks)
    timings = {"current": time.perf_counter() - t0}
    yield make_frame(job, "current", rows, 1, timings["current"], timings)
    rest = [x for x in job.all_bits if x != b]
    parts = [rest[i:i + chunk] for i in range(0, len(rest), chunk)]
    helper = ThreadPoolExecutor(1, thread_name_prefix="qsid-helper")
    ahead = _Ahead(helper, job.ex, parts, stop)
    last, done, k = time.perf_counter(), 1, 0
    try:
        while k < len(parts):
            if stop():
                return
            if on_progress:
                on_progress(done, total, f"computing b={parts[k][0]}..{parts[k][-1]} ({done + 1}/{total})")
            ahead.wait(k)
            if executor is not None and ahead.finished:
                # every b quantized (or cached): spread all remaining closed loops over the executor at once
                part, k = [x for p in parts[k:] for x in p], len(parts)
                _loops_all(helper, job, rows, part)
            else:
                # closed loops here, side by side with the quantization of the next chunk in the helper
                part, k = parts[k], k + 1
                for e in job.estimators:
                    fill_rows(job, rows, e, part)
            done += len(part)
            now = time.perf_counter()
            if done >= total or now - last >= min_interval:
                last = now
                timings["curves"] = now - t0
                yield make_frame(job, "curves", rows, done, now - t0, timings)
    finally:
        helper.shutdown(wait=False, cancel_futures=True)


class Session:
    """One browser tab: its controls, scene, plots and the worker thread that redraws them.

    Input callbacks only call :meth:`touch` (mark dirty); the worker reads the
    newest panel values, runs :func:`iter_frames` and draws a frame only if no
    newer change arrived meanwhile.
    """

    def __init__(self, app, client, values: Values):
        self.app = app
        self.client = client
        # (1) guards _gen (bumped per change), _done (last generation handled) and _closed
        self._cond = threading.Condition()
        self._gen = 0
        self._done = -1
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
        self.plots_panel.set_width(PANEL_WIDTH)
        system = get_system(values.system) if values.system in PRESETS else resolve_system(values).system
        self.controls = make_gui_elements(gui, values, system, self.touch)
        self._lesson = values.lesson  # the lesson whose settings the panel was given
        self.share = add_share_panel(self)  # keep & share: settings file, command line, exports
        self.pinned: Frame | None = None  # a frame kept for comparison (Compare tab)
        self.views = ViewPanel(gui, self.plots_panel, values, system, self.touch, self.pin, self.unpin,
                               self.start_datalength)
        self.plots = self.views.plots
        self.datalength = DataLengthRunner(app.cache, self._datalength_progress, self.touch)
        self.renderer = Renderer()
        self.portrait = PhasePortrait(client.scene)
        # (2) the tab's one worker
        self.thread = threading.Thread(target=self._loop, name=f"qsid-tab-{client.client_id}", daemon=True)
        self.thread.start()
        self.touch()

    # ----- called from viser's callback threads -----------------------------------------
    def touch(self) -> None:
        """Something changed: the worker recomputes from the newest values (older work is dropped)."""
        with self._cond:
            self._gen += 1
            self._cond.notify_all()

    def close(self, wait: bool = True) -> None:
        """Stop the worker (its computation is dropped at the next check); ``wait``: join it (10 s at most)."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        if wait and threading.current_thread() is not self.thread:
            self.thread.join(timeout=10)

    def wait_idle(self, timeout: float = 60.0) -> bool:
        """Block until every change so far is fully drawn (for tests and benchmarks)."""
        with self._cond:
            return self._cond.wait_for(lambda: self._done == self._gen, timeout)

    def pin(self) -> None:
        """Keep the frame drawn last for comparison (dashed on the error, cost and bound plots)."""
        if self.last_frame is not None:
            self.pinned = dataclasses.replace(self.last_frame, pinned=None, datalength=None)
            self.views.show_pinned(self.pinned)
            self.touch()

    def unpin(self) -> None:
        self.pinned = None
        self.views.show_pinned(None)
        self.touch()

    def start_datalength(self) -> None:
        """The data-length study for what the tab shows now; any newer change cancels it."""
        frame = self.last_frame
        if frame is None:
            return
        gen = self._gen
        self.datalength.start(frame.values, lambda: self._closed or self._gen != gen)

    def _datalength_progress(self, fraction: float, text: str) -> None:
        self.views.dl_progress.value = 100.0 * fraction
        self.views.dl_status.content = text

    @property
    def generation(self) -> int:
        """How many changes this tab has seen."""
        return self._gen

    # ----- worker ----------------------------------------------------------------------------
    def _stale(self, gen: int) -> bool:
        return self._closed or self._gen != gen

    def _loop(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._closed or self._done != self._gen)
                if self._closed:
                    return
                gen = self._gen
            try:
                gen = self._run(gen)
            except Exception as exc:  # never let the worker die: show it, keep the last view
                traceback.print_exc()
                self._show_error(f"internal error ({type(exc).__name__}): {exc}")
            with self._cond:
                self._done = gen
                self._cond.notify_all()

    def _adapt_to_system(self, gen: int, values: Values) -> tuple[int, Values] | None:
        """Fit the panel to the chosen system; returns (generation, values) to compute, None on bad input.

        The panel changes made here are the worker's own: their generation is adopted, not recomputed.
        """
        c = self.controls
        try:
            choice = resolve_system(values)
        except QsidError as exc:
            self._show_error(str(exc))
            return None
        if set_system(c, choice.system):
            with self._cond:
                gen = self._gen
            values = read_values(c)
        return gen, values

    def _open_lesson(self, gen: int) -> int:
        """A newly picked lesson sets the panel (the worker's own changes: their generation is adopted)."""
        name = self.controls["lesson"].value
        if name == self._lesson:
            return gen
        self._lesson = name
        if apply_lesson(self.controls, name, lambda v: resolve_system(v).system):
            with self._cond:
                gen = self._gen
        return gen

    def _run(self, gen: int) -> int:
        """Check, compute and draw generation ``gen``; returns the generation handled."""
        c = self.controls
        apply_pending(self)  # settings uploaded since the last run
        try:
            check_panel(c)  # every raw value (anything can come over the websocket) before it is converted
        except InputError as exc:
            self._show_error(str(exc))
            return gen
        show_weights(c)
        gen = self._open_lesson(gen)
        adapted = self._adapt_to_system(gen, read_values(c))
        if adapted is None:
            return gen
        gen, values = adapted
        self.views.set_system(resolve_system(values).system)
        values = values.replace(**self.views.values())
        for attempt in (1, 2):
            try:
                return self._compute(gen, values)
            except PoolFailure as exc:
                self.app.pool.replace(exc.executor)  # only if no other tab replaced it already
                if self._stale(gen):
                    return gen
                c.status.content = f"a worker process failed ({exc}); retrying …"
                if attempt == 2:
                    self._show_error(twice_message(exc))
        return gen

    def _compute(self, gen: int, values: Values) -> int:
        c = self.controls
        t0 = time.perf_counter()

        def progress(done: int, total: int, text: str) -> None:
            if not self._stale(gen):
                c.progress.value = 100.0 * done / total
                c.status.content = text

        frames = iter_frames(values, self.app.cache, self.app.pool.guarded(lambda: self._stale(gen)), self.app.tasks,
                             should_stop=lambda: self._stale(gen), on_progress=progress)
        try:
            while True:
                with self.app.slots:  # (4) at most a few tabs compute at once
                    if self._stale(gen):
                        return gen
                    frame = next(frames, None)
                if frame is None or self._stale(gen):
                    return gen
                if unusable(frame):  # all identifications failed, eps not finite: never 'ready'
                    self._show_error(unusable(frame))
                    return gen
                if not self._draw(frame, gen):
                    return gen
                self.timings["current" if frame.stage == "current" else "all"] = time.perf_counter() - t0
                if frame.complete:
                    c.progress.value = 100.0
                    c.status.content = (f"ready · b = {frame.bits} drawn in {self.timings['current']:.2f} s, "
                                        f"all curves in {self.timings['all']:.2f} s")
        except (PoolFailure, Superseded) as exc:
            if isinstance(exc, PoolFailure):
                raise
        except QsidError as exc:
            self._show_error(str(exc))
        except (RecursionError, OverflowError, MemoryError, ZeroDivisionError, FloatingPointError) as exc:
            self._show_error(f"these settings cannot be computed ({type(exc).__name__}: {exc}); "
                             "try smaller or less extreme values")
        finally:
            frames.close()
        return gen

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
        frame.pinned = self.pinned
        frame.datalength = self.datalength.lookup(frame.values)
        r = self.renderer.render(frame, c["axes"].value)
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
        show_frame(self, frame)
        self.frames_drawn += 1
        return True
