"""One tab's computation (:func:`iter_frames`): the engine's :class:`~qsid_core.studies.Study` of the panel's
values, its frames arranged for the views (:class:`~app.dashboard.frames.Frame`).

Threads: :func:`iter_frames` runs in the tab's worker (see the list in :mod:`app.dashboard.session`); the study's
helper thread quantizes the other word lengths while the worker runs closed loops. Every stage can be left
within about a second of a newer setting: the study checks its cancel token word length by word length, and
work in the pool through :class:`~app.dashboard.pool.Guarded` is abandoned by the pool's watchdog.
"""

from __future__ import annotations

from collections.abc import Callable, Generator, MutableMapping

from qsid_core.studies import CancelToken, LinearAtBits, Study, StudyFrame

from .frames import Frame
from .settings import ALL_BITS, LABELS, Values, estimators, resolve_system, sweep_config

__all__ = ["iter_frames"]


def _frame(f: StudyFrame, values: Values, system, notes: tuple[str, ...]) -> Frame:
    at = f.at_bits
    assert isinstance(at, LinearAtBits)
    return Frame(
        f.stage,
        values=values,
        system=system,
        bits=f.bits,
        labels=tuple(LABELS[e] for e in f.estimators),
        rows={LABELS[e]: r for e, r in f.rows.items()},
        done=f.done,
        total=f.total,
        loops={LABELS[e]: lp for e, lp in at.loops.items()},
        true_loop=at.true_loop,
        theory=at.theory,
        idents={LABELS[e]: i for e, i in at.idents.items()},
        x0=at.x0,
        notes=notes,
        elapsed=f.elapsed,
        timings=dict(f.timings),
        ex=f.experiment,  # type: ignore[arg-type]
    )


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
        The server's process pool (None: in this process) and its workers.
    should_stop : callable, optional
        Polled between word lengths; True ends the iteration (newer settings arrived).
    chunk : int
        Word lengths quantized per pass over the data. Default: all the others in one pass (each pass
        draws the dither again; one pass instead of three cut a paper-scale data change's CPU time by
        ~30%, benchmarks/bench_dashboard.py); a newer change then waits for that pass.
    min_interval : float
        A "curves" frame is yielded when this many seconds passed since the last one, and at the end.
    on_progress : callable(done, total, text), optional
        Called before each chunk ("computing b=5..9 (6/16)").
    memo : mapping, optional
        The tab's own rows from earlier computations (:func:`qsid_core.studies.full_row`): a row built
        from the same results is reused. Used by one thread at a time.

    Raises
    ------
    qsid_core.errors.QsidError
        Bad settings, data overflow, ... in plain words.
    """
    choice = resolve_system(values)
    cfg = sweep_config(values, choice.system)
    study = Study(cfg, executor, cache, tasks if executor is not None else 0, estimators(values.identification))
    cancel = CancelToken(should_stop)
    notes = tuple(choice.notes)
    for f in study.frames(int(values.bits), cancel, on_progress, min_interval, chunk, memo):
        yield _frame(f, values, choice.system, notes)
