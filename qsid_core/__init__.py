"""qsid_core: quantized system identification and the MPC built on it (the QSID-MPC letter).

Pure numerics: no GUI, no plotting, no printing, no global state. See the
modules ``systems``, ``data``, ``quantize``, ``moments``, ``identify``,
``theory``, ``riccati``, ``mpc``, ``closed_loop``, ``experiment`` and ``sweep``.
"""

from .data import Dataset, simulate
from .errors import ConfigError, DataOverflowError, IdentificationError, QsidError, SystemDefinitionError
from .experiment import Experiment, InlineExecutor, SweepConfig, parse_bits, single_threaded_blas
from .sweep import SweepResult, fit_slope, run_sweep, summary_row
from .identify import Identified, identify, relative_errors
from .moments import Moments, prepare, quantized_moments
from .closed_loop import ClosedLoops, run_closed_loops
from .mpc import MPCConfig, MPCController, MPCFailure
from .quantize import QuantizerSpec, quantize
from .systems import PRESETS, LTISystem, UncontrollableWarning, boeing747, dc_motor, dc_motor_physical, get_system, load_system
from .theory import riccati_finite, theorem1_prediction, ultimate_bound

__version__ = "0.1.0"

__all__ = [
    "ClosedLoops", "ConfigError", "DataOverflowError", "Dataset", "Experiment", "Identified", "IdentificationError", "InlineExecutor",
    "LTISystem", "MPCConfig", "MPCController", "MPCFailure", "Moments", "PRESETS", "QsidError", "QuantizerSpec",
    "SweepConfig", "SweepResult", "SystemDefinitionError", "UncontrollableWarning", "boeing747", "dc_motor",
    "dc_motor_physical", "fit_slope", "get_system", "identify", "load_system", "parse_bits", "prepare", "quantize",
    "quantized_moments", "relative_errors", "single_threaded_blas", "summary_row", "riccati_finite", "run_closed_loops", "run_sweep", "simulate",
    "theorem1_prediction", "ultimate_bound",
]
