"""ALL threading of a browser tab: its worker (:class:`Session`) and the frame generator (:func:`iter_frames`).

Concurrency in the dashboard, every mechanism in one list (each is commented where it lives):

1. ``Session._cond`` (one per tab): an input callback only bumps the tab's generation under this
   condition and wakes the worker; :meth:`Session.wait_idle` waits on it too. Those callbacks run
   where viser receives the message (its event loop); the tab's other callbacks (buttons, views) run
   in ``Session.callbacks`` (:class:`~app.dashboard.flow.TabCallbacks`, one thread per tab, at most one
   queued call per callback: a flood of changes cannot queue work without bound).
2. ``Session.thread`` (one per tab): the only thread that reads the panel,
   computes and draws; it drops a computation as soon as a newer generation exists, and starts
   at most one computation per ``MIN_GAP`` seconds (a burst of changes: only the newest is computed;
   a tab flooded with changes faster than any person makes them waits longer, up to ``MAX_GAP``).
3. the helper thread of :func:`iter_frames` (:mod:`app.frames.compute`, one per computation): quantizes the
   next chunk of word lengths while the worker runs closed loops; once every word length is quantized,
   one ``qsid-loops`` thread per estimator submits its closed loops to the pool while the worker computes
   the rows' other parts (assumptions, a-posteriori bounds).
4. ``DashboardApp.slots`` (server, :class:`~app.dashboard.flow.FairSlots`): at most a few tabs compute at
   once, served in the order they asked; a change that only redraws cached results (:data:`~app.settings.values.DISPLAY_ONLY`)
   goes first and has one slot of its own.
5. ``DashboardApp._lock`` (server): the tab registry.
6. ``SharedCache._lock`` (:mod:`app.frames.cache`): the shared cache is read and written by all of the above.
7. the process pool (:mod:`.pool`, loky's): ``Pool._lock`` guards its replacement (only of the failed executor);
   its watchdog thread abandons stale pool tasks and times out hung workers (the tab retries once).
8. signals (server ``main``): SIGINT/SIGTERM/SIGHUP blocked in every thread, taken by ``sigtimedwait`` in main
   from the first moment; the start-up (port check, warm-up, first view) runs in a ``qsid-start`` thread.
9. ``DataLengthRunner.thread`` (:mod:`app.frames.datalength`, at most one per tab): the data-length study on
   demand, in-process; cancelled when the tab's generation changes (any new change).
10. ``DashboardApp.idle`` (server, :class:`~app.dashboard.lifecycle.IdleRelease`): one timer thread once the
    last tab closed; it clears the shared cache and the workers' data unless a tab opened meanwhile. A
    ``qsid-trim`` thread (:func:`~app.dashboard.lifecycle.trim_every`) trims the server's memory until it halts.
11. ``DashboardApp.follow`` (server, :class:`~app.dashboard.follow.FollowHub`): its lock guards who leads and
    follows which code and the newest state each leader published (a leader's worker publishes, never waiting
    for a follower); its ``turn`` lock lets one follower's worker push that state at a time.
12. ``DashboardApp.figures`` (server, :class:`~app.frames.render.Figures`): a bounded cache of its own (6.) with
    its flights: a figure one tab's worker is making is waited for by another tab's worker that needs it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import threading
import time
import traceback

from app.frames.compute import iter_frames
from app.frames.datalength import DataLengthRunner
from app.frames.frame import Frame
from app.lessons.drift import lesson_markdown
from app.lessons.table import get_lesson, lesson_names, lesson_values
from app.settings.values import InputError, Values, is_nonlinear, resolve_system
from app.settings.viewcodes import ViewOpen
from qsid_core import QsidError

from .adapt import KindSwitch, LessonMark
from .controls import apply_lesson, read_values, set_system, show_weights
from .flow import TabCallbacks
from .follow import refused
from .frame_loop import Reporters, draw_frames
from .inputs import TYPING_PAUSE, check_panel, check_sent, sent_guard, unusable
from .pool import PoolFailure
from .share import show_frame
from .tabview import TabView
from .viserfix import guard_updates, set_callback_executor

__all__ = ["Session", "iter_frames", "MIN_GAP", "MAX_GAP"]

#: Seconds between the starts of two computations of one tab (changes arriving meanwhile are merged) ...
MIN_GAP = 0.1
#: ... doubled up to this after each computation that a flood dropped before anything was drawn (at least
#: FLOOD_CHANGES changes at FLOOD_RATE per second or more: no person drags a slider that fast), back to
#: MIN_GAP otherwise: a tab flooding changes cannot take the CPU from the others.
MAX_GAP = 2.0
FLOOD_CHANGES, FLOOD_RATE = 20, 200.0
#: Seconds before a computation that failed with an internal error is tried once more.
RETRY_AFTER = 0.2


class Session:
    """One browser tab: its controls, scene, plots and the worker thread that redraws them.

    Input callbacks only call :meth:`touch` (mark dirty); the worker reads the
    newest panel values, runs :func:`iter_frames` and draws a frame only if no
    newer change arrived meanwhile.
    """

    def __init__(self, app, client, values: Values, view: ViewOpen | None = None):
        self.app = app
        self.client = client
        # (1) guards _gen (bumped per change), _done (last generation handled) and _closed
        self._cond = threading.Condition()
        self._gen = 0
        self._done = -1
        self._closed = False
        self._last_start, self._gap, self._touches = 0.0, MIN_GAP, 0
        self.frames_drawn = 0
        self.last_frame: Frame | None = None
        self.timings: dict = {}
        self.rows_memo: dict = {}  # (estimator, b) -> this tab's last row and what it was built from
        gui = client.gui
        # (1) this tab's callbacks: cheap ones at once, others in one thread of its own, never queued twice
        self.callbacks = TabCallbacks(str(client.client_id))
        set_callback_executor(gui, self.callbacks)
        # a value sent is checked by the panel's rules before viser converts it; one viser refuses is explained
        # (a follower's panel takes nothing: :func:`~app.dashboard.follow.refused`)
        check = lambda h, u: refused(self, h) or check_sent(getattr(self, "controls", None), h, u)  # noqa: E731
        # a refusal stays until its input changes; the box is set back once the typing pauses
        guard_updates(gui, sent_guard(check, self._refuse, self._accept), TYPING_PAUSE)
        self.lesson_shown = values.lesson  # the lesson whose settings the panel was given
        self.pinned: Frame | None = None  # a frame kept for comparison (Compare group)
        #: the tab's panels (viser): built once, then only drawn into by this tab's worker
        self.ui = TabView(
            client,
            values,
            self.touch,
            view,
            app.views,
            lambda: self.last_frame,
            self.pin,
            self.unpin,
            self.start_datalength,
            app.figures,  # figures made once for every tab drawing the same
        )
        self.controls, self.views, self.plots = self.ui.controls, self.ui.views, self.ui.plots
        self.play, self.share, self.codes = self.ui.play, self.ui.share, self.ui.codes
        self.portrait, self.presenter, self.plots_panel = self.ui.portrait, self.ui.presenter, self.ui.plots_panel
        self.kind = KindSwitch()  # the panel of a linear or a nonlinear plant
        self.mark = LessonMark(gui, self.controls.lesson_text, lambda: self.touch(user=True))
        self.presenter.move_below([self.controls.lesson_text, self.mark.back])  # presenter mode: below the switch
        if values.lesson in lesson_names()[1:]:  # opened on a lesson (--lesson): its key view too
            self._show_lesson_view(values.lesson)
        self.datalength = DataLengthRunner(app.cache, self._datalength_progress, self.touch)
        self.follower = app.follow.attach(self)  # the leader of its code, or a follower of another's (read-only)
        # (2) the tab's one worker
        self.thread = threading.Thread(target=self._loop, name=f"qsid-tab-{client.client_id}", daemon=True)
        self.thread.start()
        self.touch()

    # ----- called from viser's callback threads -----------------------------------------
    def touch(self, user: bool = False) -> None:
        """Something changed: the worker recomputes from the newest values (older work is dropped).

        ``user``: the change came from the browser (it stops the auto-play)."""
        play = getattr(self, "play", None)
        if user and play is not None:
            play.user_changed()
        with self._cond:
            self._gen += 1
            self._touches += 1
            self._cond.notify_all()

    def close(self, wait: bool = True) -> None:
        """Stop the worker (its computation is dropped at the next check); ``wait``: join it (10 s at most)."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        self.callbacks.shutdown()
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
    def last_error(self) -> str | None:
        """The error line the tab shows (None: none)."""
        return self.ui.last_error

    @property
    def generation(self) -> int:
        """How many changes this tab has seen."""
        return self._gen

    # ----- worker ----------------------------------------------------------------------------
    def _stale(self, gen: int) -> bool:
        return self._closed or self._gen != gen

    def _loop(self) -> None:
        while True:
            with self._cond:  # idle: sleep until a change, or until the auto-play's next word length is due
                self._cond.wait_for(lambda: self._closed or self._done != self._gen, self.play.wait_time())
                if self._closed:
                    return
                idle = self._done == self._gen
            if idle:  # (everything drawn) the auto-play's next b, if due: a new generation like any change
                self.play.step()
                continue
            with self._cond:
                # (2) a burst of changes: wait out the gap since the last start, then take the newest
                self._cond.wait_for(lambda: self._closed, self._last_start + self._gap - time.monotonic())
                if self._closed:
                    return
                gen = self._gen
            self._last_start, drawn, touches = time.monotonic(), self.frames_drawn, self._touches
            gen = self._run_safely(gen)
            n, dt = self._touches - touches, max(1e-3, time.monotonic() - self._last_start)
            flooded = self.frames_drawn == drawn and self._stale(gen) and n >= FLOOD_CHANGES and n / dt >= FLOOD_RATE
            self._gap = min(MAX_GAP, 2.0 * self._gap) if flooded else MIN_GAP
            with self._cond:
                self._done = gen
                self._cond.notify_all()

    def _run_safely(self, gen: int) -> int:
        """:meth:`_run`, never raising: an internal error (viser's included) is logged with its traceback, the
        same generation is tried once more (a failed draw is retried), and if that fails too the tab shows
        one error line and keeps working on its next change."""
        for attempt in (1, 2):
            try:
                return self._run(gen)
            except Exception as exc:
                if attempt == 1:
                    traceback.print_exc()
                    with self._cond:  # a short pause, cut short by a newer change or close
                        self._cond.wait_for(lambda: self._stale(gen), RETRY_AFTER)
                    if self._stale(gen):
                        return gen
                    continue
                try:
                    self._show_error(f"internal error ({type(exc).__name__}): {exc}; change a setting to retry")
                except Exception:  # the tab cannot even show it (e.g. its connection is gone)
                    traceback.print_exc()
        return gen

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
        old = [*c.q_sliders, *c.r_sliders]
        if set_system(c, choice.system):
            self.ui.forget(old)  # (the weight sliders are made anew)
            with self._cond:
                gen = self._gen
            values = read_values(c)
        return gen, values

    def _open_lesson(self, gen: int) -> int:
        """A newly picked lesson sets the panel (the worker's own changes: their generation is adopted)."""
        name = self.controls["lesson"].value
        if name == self.lesson_shown and not self.mark.take():  # (the mark's button: the lesson set anew)
            return gen
        self.lesson_shown = name
        old = [*self.controls.q_sliders, *self.controls.r_sliders]
        if apply_lesson(self.controls, name, lambda v: resolve_system(v).system):
            self.ui.forget(old)
            with self._cond:
                gen = self._gen
            self._show_lesson_view(name)
        return gen

    def _took_lesson(self, values: Values) -> None:
        """Settings received (a view code, a file) name their lesson: shown as it is, not set anew (the received
        b, seeds ... stay; the mark says how they differ from the lesson's)."""
        self.lesson_shown = values.lesson
        c = self.controls
        c.lesson_text.content = lesson_markdown(values.lesson)
        c.lesson_text.visible = bool(c.lesson_text.content)
        self.mark.drift = ()  # the text is unmarked now; the mark follows at this run's values
        self.mark.back.visible = False
        if values.lesson in lesson_names()[1:]:  # its key view, on the received channel
            with contextlib.suppress(QsidError):  # (a bad typed system: the run below explains it)
                self.views.open_lesson(
                    get_lesson(values.lesson).plot, resolve_system(values).system, values.view_channel
                )

    def _show_lesson_view(self, name: str) -> None:
        """The plots panel on the lesson's key view (its tab forward, the view first)."""
        les, v = get_lesson(name), lesson_values(name)
        self.views.open_lesson(les.plot, resolve_system(v).system, v.view_channel)

    def _run(self, gen: int) -> int:
        """Check, compute and draw generation ``gen``; returns the generation handled."""
        c = self.controls
        self.ui.phone.apply()  # a phone's layout (the window's shape, from the camera): a follower's too
        if self.follower is not None and self.follower.mirror():  # following another tab: nothing to compute
            return gen
        received = self.ui.apply_pending()  # settings loaded (a file, a view code) since the last run
        if received is not None:
            self._took_lesson(received)
        try:
            check_panel(c)  # every raw value (anything can come over the websocket) before it is converted
        except InputError as exc:
            self._show_error(str(exc))
            return gen
        show_weights(c)
        self.play.show()
        self.presenter.apply(bool(c["presenter"].value), narrow=self.ui.phone.narrow)
        gen = self._open_lesson(gen)
        old = [*c.q_sliders, *c.r_sliders]
        if self.kind.apply(self):  # linear or nonlinear plant: its inputs shown, its defaults (worker's own change)
            self.ui.forget(old)
            with self._cond:
                gen = self._gen
        adapted = self._adapt_to_system(gen, read_values(c))
        if adapted is None:
            return gen
        gen, values = adapted
        self.views.set_system(resolve_system(values).system)
        values = values.replace(**self.views.values())
        self.mark.show(values)  # with the plots panel's own fields: a lesson sets the quantizer's channel too
        for attempt in (1, 2):
            try:
                return self._compute(gen, values)
            except PoolFailure as exc:
                self.app.pool.replace(exc.executor)  # only if no other tab replaced it already
                if self._stale(gen):
                    return gen
                c.status.content = f"a worker process failed ({exc}); retrying …"
                if attempt == 2:
                    self._show_error(f"{exc} (twice). {exc.hint}")
        return gen

    def _compute(self, gen: int, values: Values) -> int:
        t0 = time.perf_counter()
        reports = Reporters(self, gen)
        last = self.last_frame  # only drawing left if just display settings changed since a complete frame
        nonlinear = is_nonlinear(values.system)
        cheap = not nonlinear and last is not None and last.complete and values.same_results(last.values)
        frames = iter_frames(
            values,
            self.app.cache,
            self.app.pool.guarded(lambda: self._stale(gen)),
            self.app.tasks,
            should_stop=lambda: self._stale(gen),
            on_progress=reports.progress,
            memo=self.rows_memo,
        )
        return draw_frames(self, gen, frames, t0, reports, cheap, None if nonlinear else unusable)

    def _show_error(self, text: str) -> None:
        self.ui.show_error(text)

    def _refuse(self, text: str, handle) -> None:  # (viser's event loop)
        ui = getattr(self, "ui", None)  # (None: a message before the panel was built)
        if ui is not None:
            ui.refuse(handle, text)

    def _accept(self, handle) -> None:  # (viser's event loop)
        ui = getattr(self, "ui", None)
        if ui is not None:
            ui.accept(handle)

    def _draw(self, frame: Frame, gen: int) -> bool:
        """Push ``frame`` to the tab unless newer settings arrived meanwhile; True if drawn."""
        frame.pinned = self.pinned
        frame.datalength = self.datalength.lookup(frame.values)
        if not self.ui.draw(frame, lambda: self._stale(gen)):
            return False
        self.last_frame = frame
        show_frame(self.share, frame)
        self.app.follow.drawn(self, frame)  # the code keeps these settings; its followers get what was drawn
        self.frames_drawn += 1
        return True
