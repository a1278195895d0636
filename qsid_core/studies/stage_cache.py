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
from dataclasses import dataclass
from typing import Protocol, TypeVar, cast

import numpy as np
from numpy.typing import NDArray

from ..control.mpc import MPCConfig
from ..plant.data import Dataset
from ..plant.lti import LTISystem
from ..quantization.moments import Moments, PreparedData
from .config import SweepConfig
from .stage_results import BitsIdentification, TheoryAtBits

__all__ = ["Key", "StageCache", "StageKeys", "Staged"]

#: A cache key: the stage's name, then every setting the stage's result depends on.
Key = tuple[Hashable, ...]

T = TypeVar("T")
K = TypeVar("K", bound=Hashable)


@dataclass(frozen=True)
class StageKeys:
    """The cache key of every stage for one config and its resolved system.

    Each key nests the keys of the stages it is computed from (data → normalised data → moments), so a
    change of any setting reaches every stage downstream of it.

    Parameters
    ----------
    config : SweepConfig
    system : LTISystem
        ``get_system(config.system)``.
    """

    config: SweepConfig
    system: LTISystem

    def plant(self) -> Key:
        """The true system: shapes and the bytes of A, B, x0, Q, R."""
        s = self.system
        return (s.A.shape, s.B.shape, s.A.tobytes(), s.B.tobytes(), s.x0.tobytes(), s.Q.tobytes(), s.R.tobytes())

    def _data(self) -> Key:
        c = self.config
        return self.plant() + (c.trajectories, c.steps, c.data_seed, c.input_amplitude)

    def _prepared(self) -> Key:
        q = self.config.quantizer
        return self._data() + (q.range_mode, q.guard, q.fixed_range, self.config.noise)

    def _moments(self, b: int) -> Key:
        c, q = self.config, self.config.quantizer
        return self._prepared() + (
            b,
            q.dither,
            c.dither_seed,
            c.realizations,
            c.input_bits,
            c.noise_known,
            c.state_bits,
        )

    def _mpc(self) -> MPCConfig:
        """The MPC the theory stages assume: the config's, or the defaults when MPC is off."""
        return self.config.mpc or MPCConfig()

    def data(self) -> Key:
        """The unquantized data set."""
        return ("data",) + self._data()

    def prepared(self) -> Key:
        """The data (with sensor noise) normalised to the quantizer ranges."""
        return ("prep",) + self._prepared()

    def moments(self, b: int) -> Key:
        """The quantized Gram matrices of every realization at ``b``."""
        return ("mom",) + self._moments(b)

    def identification(self, b: int, estimator: str) -> Key:
        """The models ``estimator`` identifies at ``b``."""
        return ("ident", estimator) + self._moments(b)

    def theory(self, b: int) -> Key:
        """Theorem 1's prediction and the ultimate bound at ``b``."""
        c, m = self.config, self._mpc()
        return (
            "theory",
            b,
            c.theta,
            c.rho,
            m.horizon,
            m.Q,
            m.R,
            m.Qf,
            m.x0,
            c.quantizer.dither,
            c.input_bits,
            c.state_bits,
        ) + self._prepared()

    def realized_bound(self, b: int, estimator: str) -> Key:
        """The a-posteriori bound of every realization's model at ``b``."""
        c, m = self.config, self._mpc()
        return ("realized-bound", estimator, c.theta, c.rho, m.horizon, m.Q, m.R, m.Qf, m.x0) + self._moments(b)

    def small_gain(self, b: int, predicted: np.ndarray) -> Key:
        """The small-gain test of Theorem 1's predicted model ``predicted`` (shape (n, n+m)) at ``b``."""
        m = self._mpc()
        return ("small-gain", b, m.horizon, m.Q, m.R, m.Qf, predicted.tobytes()) + self.plant()

    def overload_effect(self, b: int) -> Key:
        """The predicted effect of the quantizer clipping the data at ``b``."""
        c = self.config
        return ("overload-effect", b, c.quantizer.dither, c.input_bits, c.state_bits) + self._prepared()

    def assumptions(self, b: int) -> Key:
        """Which hypotheses hold at ``b``."""
        return ("assumptions",) + self._moments(b)

    def loops(self, b: int, estimator: str, mpc: MPCConfig) -> Key:
        """The closed loops of the MPC ``mpc`` built on every model ``estimator`` identifies at ``b``."""
        return ("loops", estimator, mpc) + self._moments(b)

    def true_loop(self, mpc: MPCConfig) -> Key:
        """The MPC ``mpc`` built on the true plant (its feedback quantizer reads the data's ranges)."""
        return ("true-loop", mpc) + (self._prepared() if mpc.feedback_bits is not None else self.plant())


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
        """``mapping[key]``, or ``make()`` stored there and returned."""
        try:
            return cast(T, self.mapping[key])  # stored under this key by the same stage: a T
        except KeyError:
            pass
        value = make()
        self.mapping[key] = value
        return value

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
