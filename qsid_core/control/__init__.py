"""Control: the MPC on an identified model, many closed loops on the true plant at once, their verdicts, stability certificates and the letter's ultimate bound.

Every public name of this subpackage is listed in ``__all__``; import from here, not from its modules."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .bound import UltimateBound, riccati_finite, ultimate_bound
from .closed_loop import run_closed_loops
from .condensed_qp import CondensedQP, DaqpMPC, condense
from .controllability import controllability_margin, data_rate_bits
from .controller import MPCController
from .controllers import build_controllers
from .koopman_mpc import (
    CONVERGED_RADIUS,
    SETTLED_SHARE,
    SETTLED_TOLERANCE,
    KoopmanLoops,
    LiftedModel,
    run_koopman_loops,
)
from .loop_kernel import PDAS_ITERS, eligible, run_compiled
from .loop_noise import DISTURBANCES, LoopNoise, loop_noise
from .loop_results import ClosedLoops
from .mpc import FAILURE_KINDS, SOLVERS, TRACKING, MPCConfig
from .mpc_weights import MPCWeights
from .realized_bound import RealizedBounds, realized_bounds
from .reference import KINDS, parse_reference, reference_samples
from .riccati import LQParts, dare_batch, dare_many, dare_stabilizing, lq_parts, state_box
from .stability import certify, certify_batch, lyapunov_batch, lyapunov_gains, spectral_radius
from .stability_radius import (
    complex_stability_radii,
    complex_stability_radius,
    small_gain_holds,
    small_gain_margin,
    small_gain_margins,
)
from .timeseries import CONVERGED_REL_FLOOR, TimeSeries, saturated_steps, time_series
from .tracking import Preview
from .verdicts import OUTCOMES, STALL, WINDOW, judge

if TYPE_CHECKING:
    from .sparse_qp import OsqpMPC


def __getattr__(name: str) -> Any:
    """``OsqpMPC`` on first use: its module loads scipy.sparse, which a run without the OSQP solver never needs."""
    if name == "OsqpMPC":
        from .sparse_qp import OsqpMPC

        return OsqpMPC
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "CONVERGED_RADIUS",
    "CONVERGED_REL_FLOOR",
    "ClosedLoops",
    "CondensedQP",
    "DISTURBANCES",
    "DaqpMPC",
    "FAILURE_KINDS",
    "KINDS",
    "KoopmanLoops",
    "LQParts",
    "LiftedModel",
    "LoopNoise",
    "MPCConfig",
    "MPCController",
    "MPCWeights",
    "OUTCOMES",
    "OsqpMPC",
    "PDAS_ITERS",
    "Preview",
    "RealizedBounds",
    "SETTLED_SHARE",
    "SETTLED_TOLERANCE",
    "SOLVERS",
    "STALL",
    "TRACKING",
    "TimeSeries",
    "UltimateBound",
    "WINDOW",
    "build_controllers",
    "certify",
    "certify_batch",
    "complex_stability_radii",
    "complex_stability_radius",
    "condense",
    "controllability_margin",
    "dare_batch",
    "dare_many",
    "dare_stabilizing",
    "data_rate_bits",
    "eligible",
    "judge",
    "loop_noise",
    "lq_parts",
    "lyapunov_batch",
    "lyapunov_gains",
    "parse_reference",
    "realized_bounds",
    "reference_samples",
    "riccati_finite",
    "run_closed_loops",
    "run_compiled",
    "run_koopman_loops",
    "saturated_steps",
    "small_gain_holds",
    "small_gain_margin",
    "small_gain_margins",
    "spectral_radius",
    "state_box",
    "time_series",
    "ultimate_bound",
]
