"""A nonlinear plant's half of the study (:class:`~qsid_core.studies.study.Study`): its stages, each cached
(:class:`KoopmanExperiment`), and its frames: the current b in full, every other b's lifted models, then their
Koopman MPC loops as they finish.

:func:`~qsid_core.studies.run_sweep` runs a whole sweep for one estimator over these stages. A front end that shows
one word length first and fills the others in afterwards, for both estimators side by side, takes them piece by
piece:
the training and held-out runs, the unquantized EDMD (the reference), the quantized lifted moments of every
realization (shared by LS and BCLS: the de-biased moments are computed with them), the models and their errors per
word length and estimator, their Koopman MPC loops, the large-data limit, and the plant's own uncontrolled flow.
Each piece is cached under :func:`~qsid_core.studies.koopman_stage_key`, so a change of a setting recomputes only
what depends on it. The dither of realization ``r`` is one draw shared by every word length.

With an executor, the loops of each (b, estimator) are one executor task, submitted from at most ``workers``
threads (``qsid-koopman``); without one they run here, b by b. A cancelled token is honoured between pairs.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Generator, MutableMapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from typing import Any

import numpy as np

from ..control import KoopmanLoops, run_koopman_loops
from ..errors import IdentificationError
from ..identification import (
    ESTIMATORS,
    KoopmanModel,
    LargeDataLimit,
    LiftedMoments,
    Lifting,
    edmd,
    exact_lifted_moments,
    large_data_limit,
    prediction_error,
    quantized_lifted_realizations,
)
from ..plant import NonlinearDataset, NonlinearSystem, simulate_nonlinear
from .cache_keys import koopman_stage_key
from .config import HELD_OUT, KoopmanConfig
from .flights import memo_joined
from .stage_results import (
    ACC_KEYS,
    KoopmanModels,
    large_data_entry,
    loop_entries,
    no_exact_correction,
    predict,
    record,
    row,
)

__all__ = ["FREE_FLOW_GRID", "KoopmanExperiment", "held_out_runs", "nonlinear_frames"]

#: Initial states per axis of the plant's free flow (a grid over the training box, first two states).
FREE_FLOW_GRID = 3


def held_out_runs(system: NonlinearSystem, cfg: KoopmanConfig) -> NonlinearDataset:
    """The held-out runs of the prediction error (:data:`HELD_OUT`), seeded apart from the training runs."""
    return simulate_nonlinear(system, HELD_OUT[0], HELD_OUT[1], cfg.data_seed + 104729, cfg.input_amplitude)


class KoopmanExperiment:
    """The stages of a nonlinear sweep for ``cfg``, for any estimator, cached in ``cache``.

    Parameters
    ----------
    cfg : KoopmanConfig
        Its ``estimator`` is ignored: every method that needs one takes it.
    cache : mutable mapping, optional
        Where stage results are kept (a plain dict by default; a front end passes its shared cache).

    Raises
    ------
    ConfigError, SystemDefinitionError
        On construction: a bad dictionary or plant.
    """

    def __init__(self, cfg: KoopmanConfig, cache: MutableMapping[Any, Any] | None = None) -> None:
        self.config = cfg
        self.cache: MutableMapping[Any, Any] = {} if cache is None else cache
        self.system: NonlinearSystem = cfg.plant()
        self.lifting: Lifting = cfg.dictionary()

    def _key(self, stage: str, *extra: Any, estimator: str | None = None) -> tuple[Any, ...]:
        cfg = self.config if estimator is None else replace(self.config, estimator=estimator)
        return koopman_stage_key(cfg, stage, *extra)

    def _cached(self, key: tuple[Any, ...], make: Callable[[], Any]) -> Any:
        return memo_joined(self.cache, key, make)

    def data(self) -> tuple[NonlinearDataset, NonlinearDataset]:
        """The training runs and the held-out runs of the prediction error.

        Raises
        ------
        IdentificationError
            Fewer samples than unknowns per row of the lifted model.
        SystemDefinitionError
            The vector field raised, or returned NaN or inf.
        """
        c, s = self.config, self.system

        def make() -> tuple[NonlinearDataset, NonlinearDataset]:
            data = simulate_nonlinear(s, c.trajectories, c.steps, c.data_seed, c.input_amplitude)
            held = held_out_runs(s, c)
            return data, held

        data, held = self._cached(self._key("data"), make)
        L = self.lifting.L
        if data.T < L + s.m:
            raise IdentificationError(
                f"samples: {data.T} samples cannot fit {L + s.m} unknowns per row ({L} features + {s.m} "
                "inputs); use more runs or steps, or a smaller dictionary"
            )
        return data, held

    def reference(self) -> tuple[KoopmanModel, float]:
        """The EDMD of the unquantized training data and its prediction error on the held-out runs."""

        def make() -> tuple[KoopmanModel, float]:
            data, held = self.data()
            ref = edmd(exact_lifted_moments(data, self.lifting), self.lifting.C, "ls")
            return ref, prediction_error(ref, self.lifting, held, self.config.prediction_horizon)

        out: tuple[KoopmanModel, float] = self._cached(self._key("reference"), make)
        return out

    def reference_loop(self) -> KoopmanLoops | None:
        """The Koopman MPC of the unquantized EDMD on the true plant (None without an MPC)."""
        mpc = self.config.mpc
        if mpc is None:
            return None
        make = lambda: run_koopman_loops([self.reference()[0]], self.lifting, self.system, mpc, self.config.radius)  # noqa: E731
        out: KoopmanLoops = self._cached(self._key("reference-loop"), make)
        return out

    def moments(self, bits: Sequence[int], should_stop: Callable[[], bool] | None = None) -> bool:
        """Quantize and lift every realization at the word lengths of ``bits`` not cached yet (one pass over the
        data per realization for all of them); False if ``should_stop()`` said stop between realizations."""
        todo = [int(b) for b in bits if self._key("moments", int(b)) not in self.cache]
        if not todo:
            return True
        data, _ = self.data()
        cfg = self.config
        per: list[list[LiftedMoments]] = [[] for _ in todo]
        for seq in np.random.SeedSequence(cfg.dither_seed).spawn(cfg.realizations):
            if should_stop is not None and should_stop():
                return False
            (moms,) = quantized_lifted_realizations(data, self.lifting, todo, cfg.quantizer, [seq], unbiased=True)
            for acc, mom in zip(per, moms, strict=True):
                acc.append(mom)
        for b, acc in zip(todo, per, strict=True):
            self.cache[self._key("moments", b)] = tuple(acc)
        return True

    def limit(self, b: int) -> LargeDataLimit:
        """The large-data limit of LS quantized EDMD at word length ``b``."""

        def make() -> LargeDataLimit:
            return large_data_limit(self.data()[0], self.lifting, [int(b)], self.config.quantizer)[0]

        out: LargeDataLimit = self._cached(self._key("limit", int(b)), make)
        return out

    def models(self, b: int, estimator: str) -> KoopmanModels:
        """The models of every realization at ``b`` by ``estimator`` ("ls" or "bcls"), with their row."""
        if estimator not in ESTIMATORS:
            raise IdentificationError(f"estimator must be one of {', '.join(ESTIMATORS)}; got {estimator!r}")

        def make() -> KoopmanModels:
            self.moments([b])
            moms: tuple[LiftedMoments, ...] = self.cache[self._key("moments", int(b))]
            _, held = self.data()
            ref, _ = self.reference()
            acc: dict[str, list[Any]] = {k: [] for k in ACC_KEYS}
            for mom in moms:
                record(acc, mom, estimator, self.lifting, ref)
                predict([acc], self.lifting, held, self.config.prediction_horizon)
            out = row(int(b), acc, self.system)  # the loops' entries: row()
            correction = no_exact_correction(self.lifting, self.config.quantizer)
            limit = self.limit(b) if estimator == "ls" else None  # BCLS's limit needs no computation
            out["large_data"] = large_data_entry(limit, estimator, ref, correction)
            return KoopmanModels(int(b), estimator, tuple(acc["models"]), out)

        out: KoopmanModels = self._cached(self._key("models", int(b), estimator=estimator), make)
        return out

    def loops(self, b: int, estimator: str, executor: Any = None) -> KoopmanLoops | None:
        """The Koopman MPC of every realization's model at ``b`` on the true plant (None without an MPC).

        ``executor`` (a :class:`concurrent.futures.Executor`, optional) runs them in a worker process."""
        mpc = self.config.mpc
        if mpc is None:
            return None
        key = self._key("loops", int(b), estimator=estimator)
        hit: KoopmanLoops | None = self.cache.get(key)
        if hit is not None:
            return hit
        args = (list(self.models(b, estimator).models), self.lifting, self.system, mpc, self.config.radius)
        if executor is None:
            out = run_koopman_loops(*args)
        else:
            out = executor.submit(run_koopman_loops, *args).result()
        self.cache[key] = out
        return out

    def cached_loops(self, b: int, estimator: str) -> KoopmanLoops | None:
        """The loops at ``b`` by ``estimator`` if they are cached (None otherwise: nothing is computed)."""
        hit: KoopmanLoops | None = self.cache.get(self._key("loops", int(b), estimator=estimator))
        return hit

    @property
    def horizon(self) -> int:
        """Samples of the prediction error on the held-out runs."""
        return self.config.prediction_horizon

    def row(self, b: int, estimator: str, executor: Any = None) -> dict[str, Any]:
        """The whole row at ``b`` (:class:`~qsid_core.studies.KoopmanResult`'s, with the loops' outcomes)."""
        row = dict(self.models(b, estimator).row)
        loops = self.loops(b, estimator, executor)
        if loops is not None:
            row.update(loop_entries(loops))
        return row

    def free_flow(self, steps: int | None = None, grid: int = FREE_FLOW_GRID) -> np.ndarray:
        """The plant's own flow: uncontrolled runs (u = 0) from a grid of initial states.

        The grid has ``grid`` points per axis over ``[-a, a]`` of the first two states (the others 0), ``a`` the
        training amplitude; each run lasts ``steps`` samples (default: the loops' length, else 200). A run
        that leaves the sane box is NaN from there on.

        Returns
        -------
        ndarray, shape (grid ** min(n, 2), steps + 1, n)
        """
        s = self.system
        mpc = self.config.mpc
        T = int(steps if steps is not None else (mpc.steps if mpc is not None else 200))

        def make() -> np.ndarray:
            ax = np.linspace(-s.amplitude, s.amplitude, grid)
            pts = np.array(np.meshgrid(*([ax] * min(s.n, 2)), indexing="ij")).reshape(min(s.n, 2), -1).T
            x = np.zeros((pts.shape[0], s.n))
            x[:, : pts.shape[1]] = pts
            out = np.full((x.shape[0], T + 1, s.n), np.nan)
            out[:, 0] = x
            u = np.zeros((x.shape[0], s.m))
            alive = np.ones(x.shape[0], dtype=bool)
            for t in range(T):
                with np.errstate(all="ignore"):
                    x = np.where(alive[:, None], s.step(np.where(alive[:, None], x, 0.0), u), np.nan)
                alive &= np.all(np.isfinite(x), axis=1) & (
                    np.max(np.abs(np.nan_to_num(x, nan=np.inf)), axis=1) <= s.box
                )
                out[alive, t + 1] = x[alive]
            return out

        flow: np.ndarray = self._cached(("free-flow", T, grid, self.config.system, s.amplitude, s.box), make)
        return flow


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
