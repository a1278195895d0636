"""qsid_core: quantized system identification and the MPC built on it (the QSID-MPC letter).

Pure numerics: no GUI, no plotting, no printing, no global state. Modules:
``systems``, ``data``, ``quantize``, ``moments``, ``identify``, ``theory``,
``riccati``, ``mpc``, ``closed_loop``, ``config``, ``executors``, ``experiment``,
``sweep``, ``summary`` (typed per-b rows), ``assumptions`` (which hypotheses of
Theorem 1 and BCLS hold), ``datalength`` (error against data length),
``quantizer_demo`` (one signal quantized with and without dither),
``timeseries`` (closed loops as x(t), u(t), ||x_t||), ``records`` (one row per
b, estimator and realization: CSV, columns or a pandas DataFrame) and ``interop``
(python-control ``StateSpace`` in and out; python-control and pandas are imported
only when those functions run).
"""

from .assumptions import Assumptions
from .closed_loop import ClosedLoops, run_closed_loops
from .config import SweepConfig, parse_bits
from .data import Dataset, simulate
from .datalength import DataLengthConfig, DataLengthResult, run_datalength
from .errors import ConfigError, DataOverflowError, IdentificationError, QsidError, SystemDefinitionError
from .executors import InlineExecutor, single_threaded_blas
from .experiment import Experiment
from .identify import Identified, identify, relative_errors
from .interop import identified_statespaces, model_to_statespace, system_from_statespace, system_to_statespace
from .moments import Moments, prepare, quantized_moments
from .mpc import FailureKind, MPCConfig, MPCController, MPCFailure, MPCWeights
from .quantize import LETTER_QUANTIZER, QuantizerSpec, quantize
from .quantizer_demo import QuantizerDemo, channel_demo, quantizer_demo
from .recorded import RecordedResult, dataset_from_arrays, identify_recorded, load_recorded
from .records import COLUMNS as RECORD_COLUMNS
from .records import RealizationRecord, experiment_records, realization_records, to_columns, to_pandas, write_csv
from .riccati import LQParts
from .sweep import SummaryRow, SweepResult, fit_slope, load_result, run_sweep, summarize, summary_row
from .systems import (
    PRESETS,
    LTISystem,
    UncontrollableWarning,
    boeing747,
    dc_motor,
    dc_motor_physical,
    get_system,
    load_system,
)
from .theory import RealizedBounds, realized_bounds, riccati_finite, theorem1_prediction, ultimate_bound
from .timeseries import TimeSeries, time_series
from .version import __version__

__all__ = [
    "Assumptions",
    "ClosedLoops",
    "ConfigError",
    "DataLengthConfig",
    "DataLengthResult",
    "DataOverflowError",
    "Dataset",
    "Experiment",
    "Identified",
    "IdentificationError",
    "InlineExecutor",
    "LETTER_QUANTIZER",
    "LTISystem",
    "MPCConfig",
    "MPCController",
    "MPCFailure",
    "Moments",
    "PRESETS",
    "QsidError",
    "QuantizerDemo",
    "QuantizerSpec",
    "RealizedBounds",
    "SummaryRow",
    "SweepConfig",
    "SweepResult",
    "SystemDefinitionError",
    "TimeSeries",
    "UncontrollableWarning",
    "boeing747",
    "channel_demo",
    "dc_motor",
    "dc_motor_physical",
    "fit_slope",
    "get_system",
    "identify",
    "load_result",
    "load_system",
    "parse_bits",
    "prepare",
    "quantize",
    "quantized_moments",
    "quantizer_demo",
    "realized_bounds",
    "relative_errors",
    "riccati_finite",
    "run_closed_loops",
    "run_datalength",
    "run_sweep",
    "simulate",
    "single_threaded_blas",
    "summarize",
    "summary_row",
    "theorem1_prediction",
    "time_series",
    "ultimate_bound",
]
__all__ += ["FailureKind", "LQParts", "MPCWeights"]
__all__ += [
    "RECORD_COLUMNS",
    "RealizationRecord",
    "experiment_records",
    "realization_records",
    "to_columns",
    "to_pandas",
    "write_csv",
]
__all__ += ["RecordedResult", "dataset_from_arrays", "identify_recorded", "load_recorded", "__version__"]
__all__ += ["identified_statespaces", "model_to_statespace", "system_from_statespace", "system_to_statespace"]
