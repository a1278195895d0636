"""qsid_core exports records and interop at the top level without importing python-control or pandas."""

import subprocess
import sys
from pathlib import Path

import qsid_core
from qsid_core.plant import interop
from qsid_core.studies import records

ROOT = Path(__file__).resolve().parents[2]


def test_records_and_interop_are_exported():
    for name in (
        "RealizationRecord",
        "realization_records",
        "experiment_records",
        "to_columns",
        "to_pandas",
        "write_csv",
    ):
        assert getattr(qsid_core, name) is getattr(records, name) and name in qsid_core.__all__
    assert qsid_core.RECORD_COLUMNS == records.COLUMNS
    for name in ("system_from_statespace", "system_to_statespace", "model_to_statespace", "identified_statespaces"):
        assert getattr(qsid_core, name) is getattr(interop, name) and name in qsid_core.__all__
    assert len(set(qsid_core.__all__)) == len(qsid_core.__all__)
    assert all(hasattr(qsid_core, n) for n in qsid_core.__all__)


def test_import_qsid_core_leaves_control_pandas_and_dask_unimported():
    code = (
        "import sys, qsid_core; "
        "bad = sorted({m.split('.')[0] for m in sys.modules} & {'control', 'pandas', 'dask', 'distributed'}); "
        "print(','.join(bad))"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
