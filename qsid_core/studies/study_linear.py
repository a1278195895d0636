"""The frames of a linear plant's study (:class:`~qsid_core.studies.study.Study`): the current b in full, then
every other b in chunks.

While the current b's models, loops and bounds are computed, a helper thread quantizes the other word lengths
(:class:`_Ahead`, one expensive chunk ahead of the reader); the closed loops of each chunk then run side by side
with the next chunk's quantization, or, once every b is quantized, all at once over the executor. What is
cached already needs neither: a study whose data are all quantized starts no helper, and one whose loops are all
cached submits nothing (a change of the current b alone only reads the cache). A cancelled token is honoured
between word lengths; work already in an executor is the executor's to abandon.
"""

from __future__ import annotations

import math
import time
import weakref
from collections.abc import Callable, Generator, MutableMapping
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

from ..control.loop_results import ClosedLoops
from .experiment import Experiment
from .summary import UNKNOWN, summary_row

__all__ = ["TASK_SECONDS", "CHEAP", "task_count", "full_row", "linear_frames"]

#: Target length of one executor task (s): abandoned tasks still running delay a newer setting by about this much.
TASK_SECONDS = 0.3
#: Seconds of one worker per data sample, realization and first word length (measured: 400 x 2000 samples of the
#: dc motor, 100 realizations, one b: 1.8 s on 2 workers); each further b of the same pass adds ~11 %.
SAMPLE_SECONDS = 4.5e-8
#: A chunk quantized faster than this (s) is cheap (cached or small): the rest is queued at once.
CHEAP = 0.15

Rows = dict[str, dict[int, dict[str, Any]]]
#: (stage, rows, word lengths done) as the generator hands them to the study
Step = tuple[str, Rows, int]


def task_count(samples: int, realizations: int, bits: int, workers: int, target: float = TASK_SECONDS) -> int:
    """How many executor tasks to split ``realizations`` into for one pass over ``bits`` word lengths.

    Each task should last about ``target`` seconds (estimated from ``samples`` = trajectories x steps x
    channels / 4); at least one task per worker, at most one per realization, and a multiple of ``workers``
    where possible, so that every worker gets as many tasks of about the same size (5 tasks on 2 workers took
    three rounds of the largest; 6 take three rounds of smaller ones).
    """
    per_real = SAMPLE_SECONDS * samples * (1.0 + 0.11 * (max(1, bits) - 1))
    per_task = max(1, int(target // per_real)) if per_real > 0 else realizations
    n = max(workers, math.ceil(realizations / per_task))
    if workers > 0:
        n = math.ceil(n / workers) * workers
    return int(min(n, max(1, realizations)))


def full_row(
    ex: Experiment, est: str, b: int, lp: ClosedLoops | None, memo: MutableMapping[Any, Any] | None = None
) -> dict[str, Any]:
    """The engine's complete row at ``b`` (closed loops ``lp``, the a-posteriori bound, the assumptions, the
    saturated steps) as a JSON-ready dict (read-only: it may be reused).

    With ``memo`` (one caller's own mapping, ``(est, b)`` -> the row and what it was built from), a row built
    from the very same result objects is reused: a word-length change redraws every b's row from cached
    results, and building them again was ~30 % of its CPU time. The entry holds weak references to those
    objects and is used only if each still *is* the object passed now.
    """
    mpc = ex.config.mpc
    parts = (ex.identification(b, est), ex.theory(b), lp, ex.realized_bound(b, est), ex.assumptions(b))
    held = memo.get((est, b)) if memo is not None else None
    if held is not None and all(r() is p for r, p in zip(held[0], parts)):
        out_held: dict[str, Any] = held[1]
        return out_held
    ident, th, _, realized, assumptions = parts
    u_max = mpc.resolve(ex.system).u_max if mpc is not None else UNKNOWN
    r = summary_row(ex.system.n, ident, th, lp, u_max=u_max, realized=realized, assumptions=assumptions)
    out: dict[str, Any] = r.to_dict()
    if memo is not None:
        try:
            memo[(est, b)] = (tuple(weakref.ref(p) for p in parts), out)
        except TypeError:  # a result type without weak references: not reused
            pass
    return out


def _cached(ex: Experiment, keys: dict[Any, Any]) -> bool:
    return len(ex.cache.cached(keys)) == len(keys)


class _Ahead:
    """Quantizes ``parts`` (``ex.moments``) in the helper thread, one expensive part ahead of the reader (nothing,
    and no thread, when every part is cached)."""

    def __init__(self, helper: ThreadPoolExecutor, ex: Experiment, parts: list[list[int]], stop: Callable[[], bool]):
        self.helper, self.ex, self.parts, self.stop = helper, ex, parts, stop
        self.futures: list[Future[float | None]] = []
        self.cached = _cached(ex, {b: ex.keys.moments(b) for p in parts for b in p})

    def _task(self, part: list[int]) -> float | None:
        if self.stop():
            return None
        t = time.perf_counter()
        self.ex.moments(part)
        return time.perf_counter() - t  # seconds: decides whether the rest is queued at once

    def _submit_through(self, k: int) -> None:
        if self.cached:
            return
        while len(self.futures) <= min(k, len(self.parts) - 1):
            self.futures.append(self.helper.submit(self._task, self.parts[len(self.futures)]))

    def start(self, k: int) -> None:
        """Start quantizing part ``k`` (and part k + 1) unless started."""
        self._submit_through(k + 1)

    def wait(self, k: int) -> None:
        """Return once part ``k`` is quantized (re-raises the helper's error); part k + 1 starts meanwhile."""
        self._submit_through(k + 1)
        if self.cached:
            return
        if self.futures[k].result() is None:  # the helper skipped it (stop() was true): compute here
            self.ex.moments(self.parts[k])
        costs = [f.result() for f in self.futures if f.done() and f.exception() is None]
        if all(c is not None and c <= CHEAP for c in costs):
            self._submit_through(len(self.parts) - 1)

    @property
    def finished(self) -> bool:
        """Every part is quantized (and cached)."""
        return self.cached or len(self.futures) == len(self.parts) and all(f.done() for f in self.futures)


def _fill(ex: Experiment, rows: Rows, est: str, bits: list[int], memo: Any, loops: Any = None) -> None:
    for x in bits:
        lp = loops[x] if loops is not None else (ex.closed_loops(x, est) if ex.config.mpc is not None else None)
        rows[est][x] = full_row(ex, est, x, lp, memo)


def _loops_all(ex: Experiment, ests: tuple[str, ...], rows: Rows, bits: list[int], memo: Any) -> None:
    """Closed loops at ``bits`` for every estimator, each estimator's submitted to the executor from a thread of
    its own; meanwhile this thread computes what the rows need besides the loops (Theorem 1's assumptions, the
    a-posteriori bounds), so this process's share of the work overlaps the executor's. Loops all cached: read
    here, no thread."""
    mpc = ex.config.mpc
    if mpc is None or _cached(ex, {(b, e): ex.keys.loops(b, e, mpc) for b in bits for e in ests}):
        for e in ests:
            _fill(ex, rows, e, bits, memo)
        return
    with ThreadPoolExecutor(len(ests), thread_name_prefix="qsid-loops") as submitters:
        futs = {e: submitters.submit(ex.closed_loops_many, bits, e) for e in ests}
        for x in bits:  # first what needs no model: the loop threads identify meanwhile
            ex.assumptions(x)
        for e in ests:
            for x in bits:
                ex.realized_bound(x, e)
        for e in ests:
            _fill(ex, rows, e, bits, memo, futs[e].result())


def _rest_in_chunks(ex: Experiment, b: int, chunk: int, workers: int) -> list[list[int]]:
    """The word lengths other than ``b`` in chunks of ``chunk``; with workers, ``ex.tasks`` sized for one chunk
    (tasks of a fraction of a second: abandoned work never holds the executor)."""
    rest = [x for x in ex.config.bits if x != b]
    parts = [rest[i : i + chunk] for i in range(0, len(rest), chunk)]
    if workers > 0 and parts:
        samples = ex.config.trajectories * ex.config.steps * (ex.system.n + ex.system.m) // 4
        ex.tasks = task_count(samples, ex.config.realizations, len(parts[0]), workers)
    return parts


def linear_frames(
    ex: Experiment,
    ests: tuple[str, ...],
    b: int,
    stop: Callable[[], bool],
    workers: int,
    chunk: int,
    min_interval: float,
    progress: Callable[[int, int, str], None] | None,
    memo: MutableMapping[Any, Any] | None,
) -> Generator[Step, None, None]:
    """(stage, rows, done): the current b in full, then the other word lengths chunk by chunk (a step every
    ``min_interval`` s and at the end). ``workers``: the executor's workers (0: none; tasks sized for them)."""
    total = len(ex.config.bits)
    helper = ThreadPoolExecutor(1, thread_name_prefix="qsid-helper")
    try:
        ex.moments([b])
        ahead = _Ahead(helper, ex, _rest_in_chunks(ex, b, chunk, workers), stop)
        ahead.start(0)  # the other word lengths are quantized while the current one's rows are built
        rows: Rows = {e: {} for e in ests}
        for e in ests:
            ex.identification(b, e)
        ex.theory(b)
        for e in ests:
            _fill(ex, rows, e, [b], memo)
        yield "current", rows, 1
        parts, last, done, k = ahead.parts, time.perf_counter(), 1, 0
        while k < len(parts):
            if stop():
                return
            if progress:
                progress(done, total, f"computing b={parts[k][0]}..{parts[k][-1]} ({done + 1}/{total})")
            ahead.start(k)
            for x in parts[k]:  # needs no quantized data: computed here while the executor quantizes
                if stop():
                    return
                ex.overload_effect(x)
            ahead.wait(k)
            if workers > 0 and ahead.finished:  # every b quantized: all remaining loops at once
                part = [x for p in parts[k:] for x in p]
                _loops_all(ex, ests, rows, part, memo)
                k = len(parts)
            else:  # b by b beside the next chunk's quantization: a newer setting never waits for a chunk
                part = parts[k]
                for x in part:
                    for e in ests:
                        if stop():
                            return
                        _fill(ex, rows, e, [x], memo)
                k += 1
            done += len(part)
            now = time.perf_counter()
            if done >= total or now - last >= min_interval:
                last = now
                yield "curves", rows, done
    finally:
        helper.shutdown(wait=False, cancel_futures=True)
