import subprocess
import sys


def test_importing_engine_loads_no_gui_or_plotting():
    code = (
        "import sys, qsid_core, qsid_core.studies.experiment, qsid_core.control.mpc; "
        "bad = [m for m in sys.modules if m.split('.')[0] in ('viser', 'plotly', 'matplotlib', 'app')]; "
        "print(bad); sys.exit(1 if bad else 0)"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
