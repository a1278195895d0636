"""The stages of one tab's computation (:func:`iter_frames`): the current b in full, then every other b.

Threads: :func:`iter_frames` runs in the tab's worker (see the list in
:mod:`app.dashboard.session`); its helper thread quantizes the next chunk of word
lengths while the worker runs closed loops. Every stage can be left within about a
second of a newer setting: pool work through :class:`~app.dashboard.pool.Guarded`
is abandoned by the pool's watchdog and split into tasks of a fraction of a second
(:func:`~app.dashboard.flow.pool_tasks`), and closed loops computed here are checked
word length by word length.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Generator, MutableMapping
from concurrent.futures import Future, ThreadPoolExecutor

from .flow import pool_tasks
from .frames import Frame, fill_rows, make_frame, start
from .settings import ALL_BITS, Values

__all__ = ["iter_frames", "CHEAP"]

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

    def start(self, k: int) -> None:
        """Start quantizing part ``k`` (and part k + 1) unless started."""
        self._submit_through(k + 1)

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


def _loops_all(job, rows: dict, bits: list) -> None:
    """Closed loops at ``bits`` for every estimator, each estimator's submitted to the pool from a thread of its
    own; meanwhile this thread computes what the rows need besides the loops (Theorem 1's assumptions, the
    a-posteriori bounds), so the server's share of the work overlaps the pool's."""
    with ThreadPoolExecutor(len(job.estimators), thread_name_prefix="qsid-loops") as submitters:
        futs = {e: submitters.submit(job.ex.closed_loops_many, bits, e) for e in job.estimators}
        for x in bits:  # first what needs no model: the loop threads identify meanwhile
            job.ex.assumptions(x)
        for e in job.estimators:
            for x in bits:
                job.ex.realized_bound(x, e)
        for e, f in futs.items():
            fill_rows(job, rows, e, bits, f.result())


def _rest_in_chunks(ex, b: int, chunk: int, executor, samples: int, values: Values, tasks: int) -> list[list[int]]:
    """The word lengths other than ``b`` in chunks of ``chunk``; with a pool, ``ex.tasks`` sized for one chunk
    (tasks of a fraction of a second: abandoned work never holds the pool)."""
    rest = [x for x in ex.config.bits if x != b]
    parts = [rest[i : i + chunk] for i in range(0, len(rest), chunk)]
    if executor is not None and parts:
        channels = ex.system.n + ex.system.m
        ex.tasks = pool_tasks(samples * channels // 4, int(values.realizations), len(parts[0]), tasks)
    return parts


def _next_loops(
    job, rows, parts: list[list[int]], k: int, all_quantized: bool, stop: Callable[[], bool]
) -> tuple[list[int], int] | None:
    """The closed loops of chunk ``k``: ``(the b done, the next chunk)``, or None when stopped.

    Once every b is quantized (or cached) all remaining loops are spread over the executor at once;
    before that they run here, side by side with the quantization of the next chunk in the helper,
    one b at a time, so a newer setting never waits for a whole chunk of loops.
    """
    if all_quantized:
        part = [x for p in parts[k:] for x in p]
        _loops_all(job, rows, part)
        return part, len(parts)
    for x in parts[k]:
        for e in job.estimators:
            if stop():
                return None
            fill_rows(job, rows, e, [x])
    return parts[k], k + 1


def _curves(
    job,
    rows,
    ahead: _Ahead,
    pooled: bool,
    stop: Callable[[], bool],
    on_progress: Callable[[int, int, str], None] | None,
    min_interval: float,
    t0: float,
    timings: dict[str, float],
) -> Generator[Frame, None, None]:
    """The "curves" frames: chunk after chunk of the other word lengths (quantized by ``ahead``), their
    overload effects and closed loops, a frame every ``min_interval`` s and at the end."""
    parts, total = ahead.parts, len(ALL_BITS)
    last, done, k = time.perf_counter(), 1, 0
    while k < len(parts):
        if stop():
            return
        if on_progress:
            on_progress(done, total, f"computing b={parts[k][0]}..{parts[k][-1]} ({done + 1}/{total})")
        ahead.start(k)
        for x in parts[k]:  # needs no quantized data: computed here while the pool quantizes
            if stop():
                return
            job.ex.overload_effect(x)
        ahead.wait(k)
        step = _next_loops(job, rows, parts, k, pooled and ahead.finished, stop)
        if step is None:
            return
        part, k = step
        done += len(part)
        now = time.perf_counter()
        if done >= total or now - last >= min_interval:
            last = now
            timings["curves"] = now - t0
            yield make_frame(job, "curves", rows, done, now - t0, timings)


def iter_frames(
    values: Values,
    cache: MutableMapping | None = None,
    executor=None,
    tasks: int = 1,
    should_stop: Callable[[], bool] | None = None,
    chunk: int = len(ALL_BITS) - 1,
    min_interval: float = 0.3,
    on_progress: Callable[[int, int, str], None] | None = None,
    memo: MutableMapping | None = None,
) -> Generator[Frame, None, None]:
    """Compute what a tab shows for ``values``: a "current" frame, then "curves" frames.

    Parameters
    ----------
    values : Values
    cache : mapping, optional
        Shared :class:`~app.dashboard.cache.SharedCache` (anything a change does not touch is reused).
    executor, tasks
        Passed to :class:`~qsid_core.studies.experiment.Experiment` (e.g. the dashboard's process pool).
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
    memo : mapping, optional
        The tab's own rows from earlier computations (:func:`~app.dashboard.frames.full_row`): a row built
        from the same results is reused. Used by one thread at a time.

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
    samples = int(values.trajectories) * int(values.steps)
    helper = ThreadPoolExecutor(1, thread_name_prefix="qsid-helper")
    ahead: list[_Ahead] = []

    def quantize_the_rest(ex) -> None:
        """The current b is quantized: the helper starts on the other word lengths while its rows are built."""
        ahead.append(_Ahead(helper, ex, _rest_in_chunks(ex, b, chunk, executor, samples, values, tasks), stop))
        ahead[0].start(0)

    try:
        job, rows = start(
            values,
            cache,
            executor,
            pool_tasks(samples, int(values.realizations), 1, tasks) if executor is not None else tasks,
            memo,
            quantize_the_rest,
        )
        timings = {"current": time.perf_counter() - t0}
        yield make_frame(job, "current", rows, 1, timings["current"], timings)
        yield from _curves(job, rows, ahead[0], executor is not None, stop, on_progress, min_interval, t0, timings)
    finally:
        helper.shutdown(wait=False, cancel_futures=True)
