"""The frames of a nonlinear plant's study (:class:`~qsid_core.studies.study.Study`): the current b in full, every
other b's lifted models, then their Koopman MPC loops as they finish.

With an executor, the loops of each (b, estimator) are one executor task, submitted from at most ``workers``
threads (``qsid-koopman``); without one they run here, b by b. A cancelled token is honoured between pairs.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Generator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from .koopman_stages import KoopmanExperiment

__all__ = ["nonlinear_frames"]

Rows = dict[str, dict[int, dict[str, Any]]]
Step = tuple[str, Rows, int]


def _loops_rest(
    ex: KoopmanExperiment, rest: list[int], ests: tuple[str, ...], executor: Any, workers: int, stop: Callable[[], bool]
) -> Generator[tuple[int, str], None, None]:
    """Run the loops of every (b, estimator) of ``rest``; yields each pair once its loops are cached (in order of
    completion with an executor, b by b without one). Stops between pairs once ``stop()``."""
    pairs = [(x, e) for x in rest for e in ests]
    if executor is None:
        for x, e in pairs:
            if stop():
                return
            ex.loops(x, e)
            yield x, e
        return
    with ThreadPoolExecutor(max(1, workers), thread_name_prefix="qsid-koopman") as submitters:

        def one(x: int, e: str) -> None:
            if not stop():
                ex.loops(x, e, executor)

        futs = [(p, submitters.submit(one, *p)) for p in pairs]
        try:
            for p, f in futs:
                f.result()
                if stop():
                    return
                yield p
        finally:
            for _, f in futs:
                f.cancel()


def nonlinear_frames(
    ex: KoopmanExperiment,
    ests: tuple[str, ...],
    b: int,
    stop: Callable[[], bool],
    executor: Any,
    workers: int,
    min_interval: float,
    progress: Callable[[int, int, str], None] | None,
) -> Generator[Step, None, None]:
    """(stage, rows, done): the current b in full, a step once every b's models are identified, then steps as
    their loops finish (every ``min_interval`` s and at the end)."""
    total = len(ex.config.bits)
    ex.reference_loop()
    rows: Rows = {e: {} for e in ests}
    for e in ests:
        ex.models(b, e)
    with ThreadPoolExecutor(len(ests), thread_name_prefix="qsid-koopman") as both:  # both estimators at once
        for e, f in [(e, both.submit(ex.loops, b, e, executor)) for e in ests]:
            f.result()
            rows[e][b] = ex.row(b, e)
    yield "current", rows, 1
    rest = [x for x in ex.config.bits if x != b]
    if not rest:
        return
    if progress:
        progress(1, total, f"identifying b={rest[0]}..{rest[-1]}")
    if not ex.moments(rest, stop):
        return
    for x in rest:
        if stop():
            return
        for e in ests:
            rows[e][x] = dict(ex.models(x, e).row)
    yield "models", rows, 1
    done, last, seen = 1, time.perf_counter(), {x: 0 for x in rest}
    for x, e in _loops_rest(ex, rest, ests, executor, workers, stop):
        rows[e][x] = ex.row(x, e)
        seen[x] += 1
        if seen[x] == len(ests):
            done += 1
            if progress:
                progress(done, total, f"Koopman MPC loops: {done}/{total} word lengths")
        now = time.perf_counter()
        if done >= total or now - last >= min_interval:
            last = now
            yield "curves", rows, done
