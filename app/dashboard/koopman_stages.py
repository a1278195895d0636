"""The stages of one tab's computation for a nonlinear plant (:func:`iter_koopman_frames`): the current b in full,
then every other b's models, then their Koopman MPC loops, as the linear :func:`~app.dashboard.stages.iter_frames`.

Threads: runs in the tab's worker (see the list in :mod:`app.dashboard.session`). With the server's process
pool, the loops of each (b, estimator) are one pool task, submitted from at most ``tasks`` threads of this
generator (``qsid-koopman``) and abandoned by the pool's watchdog once newer settings arrive; without a pool they
run here, b by b. Every stage is cached in the server's shared cache under the engine's keys
(:func:`qsid_core.studies.koopman_stage_key`): a change recomputes only what depends on it.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Generator, MutableMapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from qsid_core.studies import KoopmanExperiment, KoopmanModels

from .koopman_settings import koopman_config
from .settings import ALL_BITS, LABELS, Values

__all__ = ["KoopmanFrame", "iter_koopman_frames"]


@dataclass
class KoopmanFrame:
    """One drawable state of a tab showing a nonlinear plant.

    Attributes
    ----------
    stage : {"current", "curves"}
    values : Values
    system : NonlinearSystem
    bits : int
        The current word length (drawn in 3-D, eigenvalues).
    labels : tuple of str
        Estimator labels shown (``"LS"``, ``"BCLS"``).
    rows : dict label -> {b: row}
        The rows of :class:`~qsid_core.studies.KoopmanResult` computed so far (``closed_loop_outcomes`` None for a
        b whose loops are still running).
    done, total : int
        Word lengths whose loops are done, of all.
    models, loops : dict label -> KoopmanModels / KoopmanLoops at the current b
    reference, reference_error, reference_loop : the unquantized EDMD, its prediction error and its loop
    flow : ndarray (k, T+1, n)
        The plant's free flow.
    x0 : ndarray (n,)
    horizon : int
        Samples of the prediction error.
    features : int
    data_report : str
    ex : KoopmanExperiment
    """

    kind: ClassVar[str] = "koopman"
    stage: str
    values: Values
    system: Any
    bits: int
    labels: tuple[str, ...]
    rows: dict[str, dict[int, dict[str, Any]]]
    done: int
    total: int
    models: dict[str, KoopmanModels]
    loops: dict[str, Any]
    reference: Any
    reference_error: float
    reference_loop: Any
    flow: np.ndarray
    x0: np.ndarray
    horizon: int
    features: int
    data_report: str
    ex: KoopmanExperiment | None = None
    elapsed: float = 0.0
    timings: dict[str, float] = field(default_factory=dict)
    pinned: Any = None
    datalength: Any = None

    @property
    def complete(self) -> bool:
        return self.done >= self.total

    def series(self) -> dict[str, list[dict[str, Any]]]:
        """``{label: [rows sorted by b]}`` for the views."""
        return {lab: [r[b] for b in sorted(r)] for lab, r in self.rows.items()}


def _frame(
    ex: KoopmanExperiment, values: Values, stage: str, rows: dict, done: int, b: int, ests, t0: float, timings: dict
) -> KoopmanFrame:
    ref, ref_err = ex.reference()
    return KoopmanFrame(
        stage=stage,
        values=values,
        system=ex.system,
        bits=b,
        labels=tuple(LABELS[e] for e in ests),
        rows={lab: dict(r) for lab, r in rows.items()},
        done=done,
        total=len(ALL_BITS),
        models={LABELS[e]: ex.models(b, e) for e in ests},
        loops={LABELS[e]: ex.cached_loops(b, e) for e in ests},
        reference=ref,
        reference_error=ref_err,
        reference_loop=ex.reference_loop(),
        flow=ex.free_flow(),
        x0=np.asarray(ex.config.mpc.x0 if ex.config.mpc and ex.config.mpc.x0 else ex.system.x0, dtype=float),
        horizon=ex.horizon,
        features=ex.lifting.L,
        data_report=ex.data()[0].report,
        ex=ex,
        elapsed=time.perf_counter() - t0,
        timings=dict(timings),
    )


def _loops_rest(
    ex: KoopmanExperiment, rest: list[int], ests: tuple[str, ...], executor: Any, tasks: int, stop: Callable[[], bool]
) -> Generator[tuple[int, str], None, None]:
    """Run the loops of every (b, estimator) of ``rest``; yields each pair once its loops are cached (in order of
    completion with a pool, b by b without one). Stops between pairs once ``stop()``."""
    pairs = [(x, e) for x in rest for e in ests]
    if executor is None:
        for x, e in pairs:
            if stop():
                return
            ex.loops(x, e)
            yield x, e
        return
    with ThreadPoolExecutor(max(1, tasks), thread_name_prefix="qsid-koopman") as submitters:

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


def iter_koopman_frames(
    values: Values,
    cache: MutableMapping[Any, Any] | None = None,
    executor: Any = None,
    tasks: int = 2,
    should_stop: Callable[[], bool] | None = None,
    min_interval: float = 0.3,
    on_progress: Callable[[int, int, str], None] | None = None,
) -> Generator[KoopmanFrame, None, None]:
    """Compute what a tab shows for a nonlinear plant: a "current" frame (the current b in full), a "curves"
    frame once every b's models are identified, then "curves" frames as their loops finish.

    Raises
    ------
    qsid_core.errors.QsidError
        Bad settings (:class:`~app.dashboard.settings.InputError`), a vector field that fails, too few samples.
    """
    stop = should_stop or (lambda: False)
    t0 = time.perf_counter()
    cfg, ests = koopman_config(values)
    ex = KoopmanExperiment(cfg, cache)
    b, total = int(values.bits), len(ALL_BITS)
    if on_progress:
        on_progress(0, total, f"computing b={b} (1/{total})")
    ex.reference_loop()
    rows: dict[str, dict[int, dict[str, Any]]] = {LABELS[e]: {} for e in ests}
    for e in ests:
        ex.models(b, e)
    with ThreadPoolExecutor(len(ests), thread_name_prefix="qsid-koopman") as both:  # both estimators at once
        for e, f in [(e, both.submit(ex.loops, b, e, executor)) for e in ests]:
            f.result()
            rows[LABELS[e]][b] = ex.row(b, e)
    timings = {"current": time.perf_counter() - t0}
    yield _frame(ex, values, "current", rows, 1, b, ests, t0, timings)
    rest = [x for x in cfg.bits if x != b]
    if on_progress:
        on_progress(1, total, f"identifying b={rest[0]}..{rest[-1]}")
    if not ex.moments(rest, stop):
        return
    for x in rest:
        if stop():
            return
        for e in ests:
            rows[LABELS[e]][x] = dict(ex.models(x, e).row)
    timings["models"] = time.perf_counter() - t0
    yield _frame(ex, values, "curves", rows, 1, b, ests, t0, timings)
    done, last, seen = 1, time.perf_counter(), {x: 0 for x in rest}
    for x, e in _loops_rest(ex, rest, ests, executor, tasks, stop):
        rows[LABELS[e]][x] = ex.row(x, e)
        seen[x] += 1
        if seen[x] == len(ests):
            done += 1
            if on_progress:
                on_progress(done, total, f"Koopman MPC loops: {done}/{total} word lengths")
        now = time.perf_counter()
        if done >= total or now - last >= min_interval:
            last = now
            timings["curves"] = now - t0
            yield _frame(ex, values, "curves", rows, done, b, ests, t0, timings)
