"""Training runs of a nonlinear plant (:class:`~qsid_core.plant.nonlinear.NonlinearSystem`).

The runs are as the linear presets': runs x steps with x0 ~ U[-a, a]^n (a = 2 by default) and
u ~ U[-1, 1]^m i.i.d. A run that leaves the sane box ``|x_i| <= box`` is stopped there, left out of the
data and *reported* (:attr:`NonlinearDataset.left_box`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from .data import Dataset, check_runs
from .nonlinear import NonlinearSystem

__all__ = ["NonlinearDataset", "simulate_nonlinear"]


@dataclass(frozen=True, eq=False)
class NonlinearDataset(Dataset):
    """Training data of a nonlinear plant: a :class:`~qsid_core.plant.data.Dataset` of the runs that stayed sane.

    Attributes
    ----------
    left_box : tuple of int
        Indices (among the runs drawn) of the runs that left ``|x_i| <= box``; they are not in ``states``.
    drawn : int
        Number of runs drawn (kept + left).
    """

    left_box: tuple[int, ...] = ()
    drawn: int = 0

    @property
    def report(self) -> str:
        """One line on the runs left out ("" when none)."""
        if not self.left_box:
            return ""
        shown = ", ".join(map(str, self.left_box[:10])) + (", ..." if len(self.left_box) > 10 else "")
        return f"{len(self.left_box)} of {self.drawn} runs left the sane box and are not used (runs {shown})"


def simulate_nonlinear(
    system: NonlinearSystem,
    trajectories: int = 200,
    steps: int = 100,
    seed: int | None = 0,
    input_amplitude: float = 1.0,
) -> NonlinearDataset:
    """Random-input training runs of a nonlinear plant.

    Parameters
    ----------
    system : NonlinearSystem
    trajectories : int, >= 1
        Runs drawn.
    steps : int, >= 1
        Samples per run.
    seed : int or None
        Seed of ``numpy.random.default_rng`` (inputs drawn first, then x0, as :func:`~qsid_core.plant.data.simulate`).
    input_amplitude : float, > 0
        ``A`` of u ~ U[-A, A]^m.

    Returns
    -------
    NonlinearDataset
        ``states`` (kept runs, steps + 1, n), ``inputs`` (kept runs, steps, m) and the runs left out.

    Raises
    ------
    ConfigError
        Bad sizes, or every run left the sane box.
    SystemDefinitionError
        The vector field raised or returned NaN/inf at a finite state.
    """
    if not isinstance(system, NonlinearSystem):
        raise ConfigError(f"system must be a NonlinearSystem; got {type(system).__name__}")
    trajectories, steps, input_amplitude = check_runs(seed, trajectories, steps, input_amplitude)
    n, m = system.n, system.m
    rng = np.random.default_rng(seed)
    inputs = rng.uniform(-1.0, 1.0, size=(trajectories, steps, m)) * input_amplitude
    states = np.empty((trajectories, steps + 1, n))
    states[:, 0, :] = rng.uniform(-system.amplitude, system.amplitude, size=(trajectories, n))
    alive = np.ones(trajectories, dtype=bool)
    with np.errstate(over="ignore", invalid="ignore"):
        for t in range(steps):
            idx = np.flatnonzero(alive)
            nxt = np.full((trajectories, n), np.nan)
            if idx.size:
                nxt[idx] = system.step(states[idx, t, :], inputs[idx, t, :])
            states[:, t + 1, :] = nxt
            alive &= np.all(np.abs(nxt) <= system.box, axis=1)
    left = tuple(int(i) for i in np.flatnonzero(~alive))
    if not alive.any():
        raise ConfigError(
            f"every one of {trajectories} runs of {system.name!r} left the sane box |x| <= {system.box:g}; "
            "use a smaller amplitude or fewer steps"
        )
    return NonlinearDataset(states[alive], inputs[alive], seed, input_amplitude, left_box=left, drawn=trajectories)
