"""A front end's computation (:func:`iter_frames`), for a linear and a nonlinear plant alike: the engine's
:class:`~qsid_core.studies.Study` of the panel's values (:func:`app.settings.config.study_config`), its frames
arranged for the views (:func:`~app.frames.frame.tab_frame`).

Threads: in the dashboard, :func:`iter_frames` runs in the tab's worker (see the list in
:mod:`app.dashboard.session`); the study's helper thread quantizes the other word lengths while the worker runs
closed loops. Every stage can be left within about a second of a newer setting: the study checks its cancel
token word length by word length, and work in the dashboard's pool (:class:`~app.dashboard.pool.Guarded`) is
abandoned by the pool's watchdog.
"""

from __future__ import annotations

from collections.abc import Callable, Generator, MutableMapping

from app.settings.config import study_config
from app.settings.values import ALL_BITS, Values
from qsid_core.studies import CancelToken, Study

from .frame import Frame, KoopmanFrame, tab_frame

__all__ = ["iter_frames"]


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
) -> Generator[Frame | KoopmanFrame, None, None]:
    """Compute what a tab shows for ``values``: a "current" frame, then "curves" frames (a nonlinear plant's:
    one once every b's models are identified, then more as their loops finish).

    Parameters
    ----------
    values : Values
    cache : mapping, optional
        Shared :class:`~app.frames.cache.SharedCache` (anything a change does not touch is reused).
    executor, tasks
        The server's process pool (None: in this process) and its workers.
    should_stop : callable, optional
        Polled between word lengths; True ends the iteration (newer settings arrived).
    chunk : int
        A linear plant's word lengths quantized per pass over the data. Default: all the others in one pass (each pass
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
    sc = study_config(values)  # the plant's kind chooses the configuration, not a second path
    budget = float(values.total_bits) or None  # 0: no budget study
    per_sample = int(values.bits_per_sample) or None  # 0: no allocation
    tasks = max(1, tasks) if executor is not None else 0
    study = Study(sc.config, executor, cache, tasks, sc.estimators, budget=budget, bits_per_sample=per_sample)
    for f in study.frames(int(values.bits), CancelToken(should_stop), on_progress, min_interval, chunk, memo):
        yield tab_frame(f, values, sc.system, sc.notes)
