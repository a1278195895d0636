"""A cold ``qsid --help`` loads no numerics (lazy imports); a command loads only what it needs."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

PROBE = """
import sys
from app.cli import main
try:
    main({argv!r})
except SystemExit:
    pass
print(sorted(m for m in ("numpy", "scipy", "qsid_core", "plotly", "tqdm", "control") if m in sys.modules))
"""


def _loaded(argv):
    r = subprocess.run(
        [sys.executable, "-c", PROBE.format(argv=argv)], cwd=ROOT, capture_output=True, text=True, timeout=600
    )
    assert r.returncode == 0, r.stderr
    return r.stdout.strip().splitlines()[-1]


def test_help_loads_no_numerics():
    assert _loaded(["--help"]) == "[]"
    assert _loaded([]) == "[]"  # 'give a command' error


def test_sweep_help_reads_the_engine_but_no_plotting():
    loaded = _loaded(["sweep", "--help"])
    assert "'qsid_core'" in loaded and "'plotly'" not in loaded and "'tqdm'" not in loaded


def test_a_sweep_run_loads_no_plotting_no_python_control_and_no_process_pool():
    """What a plain in-process ``qsid sweep`` needs is imported; what it does not use is not (each costs start-up:
    python-control, the OSQP path's scipy.sparse, multiprocessing for worker processes, plotting)."""
    probe = """
import contextlib, io, sys
from app.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    main(["sweep", "--bits", "4", "--realizations", "1", "--trajectories", "5", "--steps", "20", "--json", "-q"])
names = ("qsid_core", "numba", "control", "osqp", "scipy.sparse", "multiprocessing", "plotly", "loky", "dask")
print(sorted(m for m in names if m in sys.modules))
"""
    r = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().splitlines()[-1] == "['numba', 'qsid_core']"
