"""The closed-loop stages of an :class:`~qsid_core.studies.experiment.Experiment`: the MPC built on every
realization's model run on the true plant, at one b or at many through the executor, and the reference loop
built on the true plant."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..control.closed_loop import run_closed_loops
from ..control.loop_noise import FeedbackRange
from ..control.loop_results import ClosedLoops
from ..control.mpc import MPCConfig
from ..errors import ConfigError
from ..plant.lti import LTISystem
from .executors import single_threaded_blas
from .stage_cache import Staged

__all__ = ["FeedbackRange", "LoopArgs", "feedback_range", "loop_args", "loops_task", "mpc_of", "true_loop_args"]

#: ``run_closed_loops``' arguments: models, true A, true B, the MPC, the system, the feedback range.
LoopArgs = tuple[
    Sequence[tuple[np.ndarray, np.ndarray]], np.ndarray, np.ndarray, MPCConfig, LTISystem, FeedbackRange | None
]


def mpc_of(ex: Staged) -> MPCConfig:
    """The experiment's MPC settings; :class:`~qsid_core.errors.ConfigError` when MPC is switched off."""
    cfg = ex.config.mpc
    if cfg is None:
        raise ConfigError("this experiment has MPC switched off (mpc=None)")
    return cfg


def feedback_range(ex: Staged) -> FeedbackRange | None:
    """``(lo, hi, guard)`` of the training data's states, for a quantized measurement in the loop (else None)."""
    cfg = ex.config.mpc
    if cfg is None or cfg.feedback_bits is None:
        return None
    prep = ex.prepared
    return prep.lo, prep.hi, ex.config.quantizer.guard


def loop_args(ex: Staged, b: int, est: str, cfg: MPCConfig) -> LoopArgs:
    """``run_closed_loops``' arguments for the models identified by ``est`` at ``b``."""
    return (ex.identification(b, est).models, ex.system.A, ex.system.B, cfg, ex.system, feedback_range(ex))


def true_loop_args(ex: Staged, cfg: MPCConfig) -> LoopArgs:
    """``run_closed_loops``' arguments for the MPC built on the true ``(A, B)``."""
    s = ex.system
    return ([(s.A, s.B)], s.A, s.B, cfg, s, feedback_range(ex))


def loops_task(args: LoopArgs) -> ClosedLoops:
    """``run_closed_loops(*args)`` with one BLAS thread (module level: picklable for process pools)."""
    with single_threaded_blas():
        return run_closed_loops(*args)
