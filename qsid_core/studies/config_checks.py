"""Checks of the engine's composite arguments (which need the config classes themselves).

Kept apart from :mod:`qsid_core.validate` (imported by every module) so that there is no import cycle:
this module imports :mod:`~qsid_core.control.mpc` and :mod:`~qsid_core.plant.systems` and is imported by the sweep modules.
"""

from __future__ import annotations

from concurrent.futures import Executor
from pathlib import Path
from typing import Any

from ..control.mpc import MPCConfig
from ..errors import ConfigError, check_float, short_repr
from ..plant.lti import LTISystem
from ..validate import MAX_MAGNITUDE

__all__ = ["check_sweep_parts", "check_run_args"]


def check_sweep_parts(system: Any, mpc: Any, rho: Any) -> None:
    """Types of :class:`~qsid_core.studies.experiment.SweepConfig`'s ``system`` and ``mpc``, and the range of ``rho``."""
    if not isinstance(system, (str, Path, LTISystem)):
        raise ConfigError(
            f"system must be a preset name, a path to a .toml/.json file or an LTISystem; "
            f"got {short_repr(system)} ({type(system).__name__})"
        )
    if mpc is not None and not isinstance(mpc, MPCConfig):
        raise ConfigError(
            f"mpc must be an MPCConfig, or None to skip the closed loops; got {short_repr(mpc)} ({type(mpc).__name__})"
        )
    if rho is not None:
        check_float("rho", rho, 0.0, MAX_MAGNITUDE, lo_open=True)


def check_run_args(config: Any, config_type: type, executor: Any, progress: Any) -> None:
    """Arguments of :func:`~qsid_core.studies.sweep.run_sweep` / :class:`~qsid_core.studies.experiment.Experiment`.

    ``config_type`` is :class:`~qsid_core.studies.experiment.SweepConfig` (passed in: that module imports this one).
    """
    if not isinstance(config, config_type):
        raise ConfigError(f"config must be a SweepConfig; got {type(config).__name__}")
    if executor is not None and not isinstance(executor, Executor) and not callable(getattr(executor, "submit", None)):
        raise ConfigError(f"executor must be a concurrent.futures.Executor (or None); got {type(executor).__name__}")
    if progress is not None and not callable(progress):
        raise ConfigError(
            f"progress must be a function progress(done, total, stage) or None; got {type(progress).__name__}"
        )
