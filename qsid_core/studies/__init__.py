"""Studies: configurations, the staged and cached experiment, sweeps over word lengths, summaries and records, "how many bits", data length and recorded data.

Every public name of this subpackage is listed in ``__all__``; import from here, not from its modules."""

from __future__ import annotations

from .assumptions import (
    FIT_TOLERANCE,
    LARGE_DATA_RATIO,
    OVERLOAD_EFFECT_RATIO,
    STATIONARITY_MARGIN,
    Assumptions,
    assess,
    finite_data_fluctuation,
    range_words,
)
from .bits import bits_needed
from .bits_answer import BitsAnswer, BitsRow, answer_from_rows, from_on, wilson_interval
from .bits_certificate import (
    CERTIFY_TOLERANCE,
    certificate,
    certified_own_models,
    certified_own_models_at,
    predicted_small_gain,
    predicted_small_gains,
    realized_small_gain,
)
from .bits_cost import LOOP_COST_TOLERANCE, LOOP_TIME_CONSTANTS, loop_length
from .budget import KNEE_TOLERANCE, BudgetConfig, BudgetResult, run_budget, runs_bought
from .budget_allocation import AllocationResult, propose_allocation, run_allocation, uniform_allocation
from .cache_keys import (
    KEY_PARTS,
    KOOPMAN_KEY_PARTS,
    KOOPMAN_NOT_IN_KEYS,
    KOOPMAN_STAGE_GROUPS,
    NOT_IN_KEYS,
    STAGE_GROUPS,
    config_paths,
    group_values,
    koopman_stage_key,
    stage_key,
    system_key,
)
from .clipping import clipping_effect
from .config import (
    KOOPMAN_MPC,
    KOOPMAN_MPC_UNUSED,
    NO_CERTIFICATES,
    KoopmanConfig,
    SweepConfig,
    parse_bits,
    parse_input_bits,
    parse_noise,
    parse_state_bits,
)
from .config_checks import check_run_args, check_sweep_parts
from .datalength import (
    DEFAULT_SAMPLES,
    DataLengthConfig,
    DataLengthResult,
    DataLengthRow,
    datalength_key,
    run_datalength,
    runs_and_steps,
)
from .executors import InlineExecutor, single_threaded_blas
from .experiment import Experiment
from .flights import Flights
from .outputs import output_target, replace_atomically
from .recorded import RecordedResult, dataset_from_arrays, identify_recorded, load_recorded, theorem1_on_data
from .records import (
    COLUMNS,
    RealizationRecord,
    experiment_records,
    realization_records,
    to_columns,
    to_pandas,
    write_csv,
)
from .stage_results import BitsIdentification, KoopmanModels, TheoryAtBits
from .study import CancelToken, LinearAtBits, NonlinearAtBits, Study, StudyFrame
from .study_budget import Bandwidth, bandwidth, bandwidth_key
from .study_linear import full_row, task_count
from .study_nonlinear import FREE_FLOW_GRID, KoopmanExperiment
from .summary import Stats, SummaryRow, build_row, fit_slope, json_clean, summary_row
from .sweep import KoopmanResult, run_koopman_sweep, run_sweep, summarize
from .sweep_result import RESULT_FORMAT, StoredRow, SweepResult, load_result
from .warmup import (
    COMPILED_KERNELS,
    compile_kernels,
    kernel_cache_dir,
    kernel_names,
    kernel_steps,
    kernels_cached,
    one_per_size,
)

__all__ = [
    "AllocationResult",
    "Assumptions",
    "Bandwidth",
    "BitsAnswer",
    "BitsIdentification",
    "BitsRow",
    "BudgetConfig",
    "BudgetResult",
    "CERTIFY_TOLERANCE",
    "COLUMNS",
    "COMPILED_KERNELS",
    "CancelToken",
    "DEFAULT_SAMPLES",
    "DataLengthConfig",
    "DataLengthResult",
    "DataLengthRow",
    "Experiment",
    "FIT_TOLERANCE",
    "FREE_FLOW_GRID",
    "Flights",
    "InlineExecutor",
    "KEY_PARTS",
    "KNEE_TOLERANCE",
    "KOOPMAN_KEY_PARTS",
    "KOOPMAN_MPC",
    "KOOPMAN_MPC_UNUSED",
    "KOOPMAN_NOT_IN_KEYS",
    "KOOPMAN_STAGE_GROUPS",
    "KoopmanConfig",
    "KoopmanExperiment",
    "KoopmanModels",
    "KoopmanResult",
    "LARGE_DATA_RATIO",
    "LOOP_COST_TOLERANCE",
    "LOOP_TIME_CONSTANTS",
    "LinearAtBits",
    "NOT_IN_KEYS",
    "NO_CERTIFICATES",
    "NonlinearAtBits",
    "OVERLOAD_EFFECT_RATIO",
    "RESULT_FORMAT",
    "RealizationRecord",
    "RecordedResult",
    "STAGE_GROUPS",
    "STATIONARITY_MARGIN",
    "Stats",
    "StoredRow",
    "Study",
    "StudyFrame",
    "SummaryRow",
    "SweepConfig",
    "SweepResult",
    "TheoryAtBits",
    "answer_from_rows",
    "assess",
    "bandwidth",
    "bandwidth_key",
    "bits_needed",
    "build_row",
    "certificate",
    "certified_own_models",
    "certified_own_models_at",
    "check_run_args",
    "check_sweep_parts",
    "clipping_effect",
    "compile_kernels",
    "config_paths",
    "datalength_key",
    "dataset_from_arrays",
    "experiment_records",
    "finite_data_fluctuation",
    "fit_slope",
    "from_on",
    "full_row",
    "group_values",
    "identify_recorded",
    "json_clean",
    "kernel_cache_dir",
    "kernel_names",
    "kernel_steps",
    "kernels_cached",
    "koopman_stage_key",
    "load_recorded",
    "load_result",
    "loop_length",
    "one_per_size",
    "output_target",
    "parse_bits",
    "parse_input_bits",
    "parse_noise",
    "parse_state_bits",
    "predicted_small_gain",
    "predicted_small_gains",
    "propose_allocation",
    "range_words",
    "realization_records",
    "realized_small_gain",
    "replace_atomically",
    "run_allocation",
    "run_budget",
    "run_datalength",
    "run_koopman_sweep",
    "run_sweep",
    "runs_and_steps",
    "runs_bought",
    "single_threaded_blas",
    "stage_key",
    "summarize",
    "summary_row",
    "system_key",
    "task_count",
    "theorem1_on_data",
    "to_columns",
    "to_pandas",
    "uniform_allocation",
    "wilson_interval",
    "write_csv",
]
