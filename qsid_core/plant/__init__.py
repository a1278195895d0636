"""The plant: LTI systems, presets and system files, python-control interop, and the training runs it produces.

Every public name of this subpackage is listed in ``__all__``; import from here, not from its modules."""

from __future__ import annotations

from .data import OVERFLOW_LIMIT, Dataset, simulate
from .interop import (
    OUTPUT_RULES,
    identified_statespaces,
    model_to_statespace,
    system_from_statespace,
    system_to_statespace,
)
from .lti import MAX_INPUTS, MAX_STATES, LTISystem, UncontrollableWarning
from .nonlinear import (
    NONLINEAR_PRESETS,
    NonlinearSystem,
    VectorField,
    get_nonlinear,
    is_nonlinear,
    is_nonlinear_file,
    load_nonlinear,
    nonlinear_from_dict,
    rk4_step,
)
from .nonlinear_data import NonlinearDataset, simulate_nonlinear
from .systems import PRESETS, boeing747, dc_motor, dc_motor_physical, get_system, load_system, system_from_dict

__all__ = [
    "Dataset",
    "LTISystem",
    "MAX_INPUTS",
    "MAX_STATES",
    "NONLINEAR_PRESETS",
    "NonlinearDataset",
    "NonlinearSystem",
    "OUTPUT_RULES",
    "OVERFLOW_LIMIT",
    "PRESETS",
    "UncontrollableWarning",
    "VectorField",
    "boeing747",
    "dc_motor",
    "dc_motor_physical",
    "get_nonlinear",
    "get_system",
    "identified_statespaces",
    "is_nonlinear",
    "is_nonlinear_file",
    "load_nonlinear",
    "load_system",
    "model_to_statespace",
    "nonlinear_from_dict",
    "rk4_step",
    "simulate",
    "simulate_nonlinear",
    "system_from_dict",
    "system_from_statespace",
    "system_to_statespace",
]
