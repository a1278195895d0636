"""The staged cache of an :class:`~qsid_core.studies.experiment.Experiment`: where stage results are kept,
the one place their keys are written, and what a stage sees of its experiment.

Every key starts with the stage's name and contains everything the stage's result depends on, so one
mapping can serve many experiments (browser tabs, systems, settings) at once. :class:`StageKeys` builds
them from a config and its resolved system; :class:`StageCache` stores and finds results in a mapping that
may be shared and bounded (it may drop any entry at any moment). :class:`Staged` is the part of an
experiment the stage modules use, so they need not import the experiment that calls them.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Iterable, Mapping, MutableMapping, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray

from ..control.mpc import MPCConfig
from ..plant.data import Dataset
from ..plant.lti import LTISystem
from ..quantization.moments import Moments, PreparedData
from .cache_keys import stage_key, system_key
from .config import SweepConfig
from .flights import Flights, flights_of, memo_joined
from .stage_results import BitsIdentification, TheoryAtBits

__all__ = ["Key", "StageCache", "StageKeys", "Staged"]

#: A cache key: the stage's name, then every setting the stage's result depends on.
Key = tuple[Hashable, ...]

T = TypeVar("T")
K = TypeVar("K", bound=Hashable)
#: ``deliver(k, value)``: a batch's computation hands over the result for ``k``.
Deliver = Callable[[K, object], None]


@dataclass(frozen=True)
class StageKeys:
    """The cache key of every stage for one config and its resolved system, generated from the config's
    fields (:mod:`qsid_core.studies.cache_keys`: each stage's key holds the values of the key groups it
    depends on, so a change of any setting reaches every stage downstream of it).

    Parameters
    ----------
    config : SweepConfig
    system : LTISystem
        ``get_system(config.system)``.
    """

    config: SweepConfig
    system: LTISystem
    #: per stage, the part of its key after the name and the per-call parts (built once per config)
    _tails: dict[str, Key] = field(default_factory=dict, init=False, repr=False, compare=False)

    def plant(self) -> Key:
        """The true system: shapes and the bytes of A, B, x0, Q, R."""
        return system_key(self.system)

    def _key(self, stage: str, *extra: Hashable) -> Key:
        try:
            tail = self._tails[stage]
        except KeyError:
            tail = self._tails[stage] = stage_key(self.config, self.system, stage)[1:]
        return (stage, *extra, *tail)

    def data(self) -> Key:
        """The unquantized data set."""
        return self._key("data")

    def prepared(self) -> Key:
        """The data (with sensor noise) normalised to the quantizer ranges."""
        return self._key("prep")

    def moments(self, b: int) -> Key:
        """The quantized Gram matrices of every realization at ``b``."""
        return self._key("mom", b)

    def identification(self, b: int, estimator: str) -> Key:
        """The models ``estimator`` identifies at ``b``."""
        return self._key("ident", estimator, b)

    def theory(self, b: int) -> Key:
        """Theorem 1's prediction and the ultimate bound at ``b``."""
        return self._key("theory", b)

    def realized_bound(self, b: int, estimator: str) -> Key:
        """The a-posteriori bound of every realization's model at ``b``."""
        return self._key("realized-bound", estimator, b)

    def small_gain(self, b: int, predicted: np.ndarray) -> Key:
        """The small-gain test of Theorem 1's predicted model ``predicted`` (shape (n, n+m)) at ``b``."""
        return self._key("small-gain", b, predicted.tobytes())

    def overload_effect(self, b: int) -> Key:
        """The predicted effect of the quantizer clipping the data at ``b``."""
        return self._key("overload-effect", b)

    def assumptions(self, b: int) -> Key:
        """Which hypotheses hold at ``b``."""
        return self._key("assumptions", b)

    def loops(self, b: int, estimator: str, mpc: MPCConfig) -> Key:
        """The closed loops of the MPC ``mpc`` (the config's) built on every model ``estimator`` identifies at ``b``."""
        assert mpc == self.config.mpc  # the loop group is the config's MPC
        return self._key("loops", estimator, b)

    def own_small_gain(self, b: int, estimator: str) -> Key:
        """The small-gain test of each realization's own model at ``b`` with the gain of its loop (stored
        with the gain's bytes: the gain is the unconstrained law's, which no closed-loop setting changes)."""
        return self._key("own-small-gain", estimator, b)

    def true_loop(self, mpc: MPCConfig) -> Key:
        """The MPC ``mpc`` (the config's) built on the true plant (its feedback quantizer reads the data's ranges)."""
        assert mpc == self.config.mpc
        return self._key("true-loop" if mpc.feedback_bits is None else "true-loop-fed")


class StageCache:
    """Stage results in a mapping, which may be shared with other experiments and bounded.

    A value is always returned from here, never read back after storing: a shared, bounded cache (the
    dashboard's) may drop any entry at any moment while other threads store theirs.

    Parameters
    ----------
    mapping : MutableMapping, optional
        Where results are kept (default: a private dict).
    """

    def __init__(self, mapping: MutableMapping[Key, object] | None = None) -> None:
        self.mapping: MutableMapping[Key, object] = {} if mapping is None else mapping

    def memo(self, key: Key, make: Callable[[], T]) -> T:
        """``mapping[key]``, or ``make()`` stored there and returned (joining another thread computing it now,
        when the mapping carries :class:`~qsid_core.studies.flights.Flights`)."""
        return memo_joined(self.mapping, key, make)

    def batch(self, keys: Mapping[K, Key], compute: Callable[[list[K], Deliver[K]], None]) -> dict[K, object]:
        """The results of every key of ``keys``, each taken from the mapping, from the thread computing it now,
        or computed here by one call ``compute(todo, deliver)``, which calls ``deliver(k, value)`` for each
        ``k`` of ``todo`` as soon as it has it (so threads waiting for that key get it at once).

        A key ``compute`` fails to deliver (it raised, or skipped it) is released to its waiters, who then
        compute it themselves.
        """
        out = self.cached(keys)
        todo = [k for k in keys if k not in out]
        flights = flights_of(self.mapping)
        while todo:
            if flights is None:
                mine, theirs = todo, {}
            else:
                by_key: dict[Hashable, K] = {keys[k]: k for k in todo}
                owned, running = flights.claim(by_key)
                mine, theirs = [by_key[key] for key in owned], {by_key[key]: f for key, f in running.items()}
            if mine:
                self._compute_owned(keys, mine, compute, out, flights)
            todo = []
            for k, fut in theirs.items():
                ok, value = flights.wait(fut) if flights is not None else (False, None)
                if ok:
                    out[k] = value
                else:
                    todo.append(k)  # its owner failed: compute it here (or join whoever does)
        return {k: out[k] for k in keys}

    def _compute_owned(
        self,
        keys: Mapping[K, Key],
        mine: list[K],
        compute: Callable[[list[K], Deliver[K]], None],
        out: dict[K, object],
        flights: Flights | None,
    ) -> None:
        def deliver(k: K, value: object) -> None:
            self.mapping[keys[k]] = value
            out[k] = value
            if flights is not None:
                flights.land(keys[k], value)

        try:
            compute(mine, deliver)
        finally:
            if flights is not None:
                flights.abort(keys[k] for k in mine if k not in out)
        missing = [k for k in mine if k not in out]
        if missing:
            raise RuntimeError(f"a stage computed no result for {missing}")

    def cached(self, keys: Mapping[K, Key]) -> dict[K, object]:
        """``{k: mapping[keys[k]]}`` for the keys the mapping holds now."""
        out: dict[K, object] = {}
        for k, key in keys.items():
            try:
                out[k] = self.mapping[key]
            except KeyError:
                pass
        return out

    def store(self, items: Iterable[tuple[Key, object]]) -> None:
        """Store every ``(key, value)`` of ``items``."""
        for key, value in items:
            self.mapping[key] = value


class Staged(Protocol):
    """What a stage uses of its :class:`~qsid_core.studies.experiment.Experiment` (the earlier stages, cached)."""

    config: SweepConfig
    system: LTISystem
    executor: Executor
    tasks: int
    keys: StageKeys
    cache: StageCache

    @property
    def data(self) -> Dataset:
        """The unquantized data set."""

    @property
    def prepared(self) -> PreparedData:
        """The data normalised to the quantizer ranges."""

    @property
    def Sigma(self) -> NDArray[np.float64]:
        """``Psi Psi^T / T`` of the unquantized data, shape (n+m, n+m)."""

    def noise_variance(self) -> NDArray[np.float64]:
        """Sensor noise variance per channel, shape (n+m,)."""

    def moments(self, bits: str | int | Sequence[int]) -> dict[int, list[Moments]]:
        """Quantized Gram matrices per b and realization."""

    def identification(self, b: int, estimator: str | None = None) -> BitsIdentification:
        """Identified models at ``b`` for every realization."""

    def theory(self, b: int) -> TheoryAtBits:
        """Theorem 1's prediction and the ultimate bound at ``b``."""

    def overload_effect(self, b: int) -> NDArray[np.float64]:
        """The predicted effect of the quantizer clipping the data at ``b``, shape (n, n+m)."""
