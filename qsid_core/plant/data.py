"""Training data: random-input trajectories of the true system (the letter's Section V).

``trajectories`` runs of ``steps`` steps; x0 ~ U[-a, a]^n and u_t ~ U[-A, A]^m i.i.d.
with state amplitude ``a`` (default 1) and input amplitude ``A`` (default 1: the letter's U[-1, 1]; defaults 200 x 1000,
as in the letter). A smaller ``A`` makes the signal small against a fixed
quantizer range.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, DataOverflowError, check_float, check_int
from .lti import LTISystem
from .memory import check_memory

__all__ = ["Dataset", "simulate", "OVERFLOW_LIMIT"]

#: States whose magnitude exceeds this are treated as overflow (an unstable A).
OVERFLOW_LIMIT = 1e12


@dataclass(frozen=True, eq=False)
class Dataset:
    """Unquantized training data.

    Attributes
    ----------
    states : ndarray, shape (trajectories, steps + 1, n)
        ``x_0 .. x_steps`` of every run.
    inputs : ndarray, shape (trajectories, steps, m)
        ``u_0 .. u_{steps-1}`` of every run.
    seed : int or None
        The seed it was drawn with.
    input_amplitude : float
        ``A`` of u ~ U[-A, A] (input units).
    """

    states: np.ndarray
    inputs: np.ndarray
    seed: int | None = None
    input_amplitude: float = 1.0

    @property
    def trajectories(self) -> int:
        return int(self.states.shape[0])

    @property
    def steps(self) -> int:
        return int(self.inputs.shape[1])

    @property
    def n(self) -> int:
        return int(self.states.shape[2])

    @property
    def m(self) -> int:
        return int(self.inputs.shape[2])

    @property
    def T(self) -> int:
        """Number of regression samples (columns of Psi): trajectories * steps."""
        return self.trajectories * self.steps

    def extremes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per channel ``(min, max)`` of Psi's rows, then of X+'s rows: shapes (n+m,), (n+m,), (n,), (n,).

        Computed once per dataset (the assumption checks ask at every word length).
        """
        got = self.__dict__.get("_extremes")
        if got is None:
            x, xp, u = self.states[:, :-1, :], self.states[:, 1:, :], self.inputs
            got = (
                np.concatenate([x.min(axis=(0, 1)), u.min(axis=(0, 1))]),
                np.concatenate([x.max(axis=(0, 1)), u.max(axis=(0, 1))]),
                xp.min(axis=(0, 1)),
                xp.max(axis=(0, 1)),
            )
            self.__dict__["_extremes"] = got  # a frozen dataclass: kept beside its fields
        return got

    def matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """``(Psi, X+)`` of the letter's eq. (4), shapes (n+m, T) and (n, T)."""
        X = self.states[:, :-1, :].reshape(-1, self.n)
        Xp = self.states[:, 1:, :].reshape(-1, self.n)
        U = self.inputs.reshape(-1, self.m)
        return np.hstack([X, U]).T, Xp.T


def check_runs(seed: int | None, trajectories: int, steps: int, input_amplitude: float) -> tuple[int, int, float]:
    """The checked ``(trajectories, steps, input_amplitude)`` of a set of training runs (``seed``: None or >= 0).

    Raises
    ------
    ConfigError
        Naming the field that is out of range or not a number.
    """
    if seed is not None:
        check_int("seed", seed, 0)
    return (
        check_int("trajectories", trajectories, 1, 100_000),
        check_int("steps", steps, 1, 1_000_000),
        check_float("input amplitude", input_amplitude, 0.0, 1e12, lo_open=True),
    )


def simulate(
    system: LTISystem,
    trajectories: int = 200,
    steps: int = 1000,
    seed: int | None = 0,
    input_amplitude: float = 1.0,
    state_amplitude: float = 1.0,
) -> Dataset:
    """Simulate ``trajectories`` runs of ``x+ = A x + B u`` with uniform random x0 and inputs.

    Parameters
    ----------
    system : LTISystem
        The true plant.
    trajectories : int, >= 1
        Number of independent runs.
    steps : int, >= 1
        Steps per run; each run contributes ``steps`` regression samples.
    seed : int or None
        Seed of ``numpy.random.default_rng``.
    input_amplitude : float, > 0
        ``A`` of u_t ~ U[-A, A]^m (input units; default 1, the letter's). The same
        seed gives the same unit draws scaled by ``A``.
    state_amplitude : float, > 0
        ``a`` of the initial states x0 ~ U[-a, a]^n (state units; default 1, the letter's),
        scaled the same way.

    Raises
    ------
    ConfigError
        If sizes are not positive integers, the amplitude is not a positive
        number, or there are fewer samples than unknowns per row (n + m).
    DataOverflowError
        If a state exceeds :data:`OVERFLOW_LIMIT` (unstable A with long runs).
    """
    if not isinstance(system, LTISystem):
        raise ConfigError(f"system must be an LTISystem; got {type(system).__name__}")
    trajectories, steps, input_amplitude = check_runs(seed, trajectories, steps, input_amplitude)
    state_amplitude = check_float("state amplitude", state_amplitude, 0.0, 1e12, lo_open=True)
    n, m = system.n, system.m
    if trajectories * steps < n + m:
        raise ConfigError(
            f"trajectories*steps = {trajectories * steps} samples cannot identify {n}+{m} unknowns per row; "
            f"use at least {n + m} samples"
        )
    check_memory(
        f"simulate({trajectories} trajectories x {steps} steps)",
        8.0 * trajectories * ((steps + 1) * n + steps * (m + n)),
        "use fewer trajectories or steps",
    )
    rng = np.random.default_rng(seed)
    states = np.empty((trajectories, steps + 1, n))
    inputs = rng.uniform(-1.0, 1.0, size=(trajectories, steps, m))
    if input_amplitude != 1.0:
        inputs *= input_amplitude
    states[:, 0, :] = rng.uniform(-1.0, 1.0, size=(trajectories, n))
    if state_amplitude != 1.0:
        states[:, 0, :] *= state_amplitude
    AT, BT = system.A.T, system.B.T
    Bu = inputs @ BT  # (traj, steps, n)
    x = states[:, 0, :]
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(steps):
            x = x @ AT + Bu[:, t, :]
            states[:, t + 1, :] = x
            if t % 64 == 63 or t == steps - 1:
                peak = np.abs(x).max()
                if not np.isfinite(peak) or peak > OVERFLOW_LIMIT:
                    rho = float(np.abs(np.linalg.eigvals(system.A)).max())
                    raise DataOverflowError(
                        f"simulated states exceed {OVERFLOW_LIMIT:.0e} at step {t + 1} of {steps} "
                        f"(spectral radius of A is {rho:.3g} > 1); use fewer steps or a stable A"
                    )
    return Dataset(states, inputs, seed, input_amplitude)


def with_sensor_noise(data: Dataset, sigma: float | Sequence[float], seed: int) -> Dataset:
    """The data as a sensor records them: Gaussian noise of standard deviation ``sigma`` on every state.

    Parameters
    ----------
    data : Dataset
        Noise-free states (trajectories, steps + 1, n) and inputs (trajectories, steps, m).
    sigma : float or sequence of float, length 1 or n
        Standard deviation per state (one value: every state). Inputs are commanded, not measured:
        they stay exact.
    seed : int
        Seeds the noise stream, ``SeedSequence(seed).spawn(2)[1]`` (independent of the data's own stream).

    Returns
    -------
    Dataset
        The same inputs, states plus noise (a new array; ``data`` is untouched).

    Raises
    ------
    ConfigError
        If ``sigma`` has neither 1 nor n entries.
    """
    from ..errors import ConfigError

    s = np.asarray(sigma, dtype=float).reshape(-1)
    if s.size not in (1, data.n):
        raise ConfigError(f"noise has {s.size} values; give one for every state or one per state ({data.n})")
    if not np.any(s > 0):
        return data
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[1])
    noisy = data.states + rng.standard_normal(data.states.shape) * np.broadcast_to(s, (data.n,))
    return Dataset(noisy, data.inputs, data.seed, data.input_amplitude)
