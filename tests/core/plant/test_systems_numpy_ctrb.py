"""Building a system needs no python-control (cold CLI start): the numpy controllability matrix and the
zero-order hold agree with python-control's ``ctrb`` and ``c2d``."""

import subprocess
import sys
from pathlib import Path

import control
import numpy as np
import pytest

from qsid_core.plant.lti import LTISystem
from qsid_core.plant.systems import dc_motor_physical

ROOT = Path(__file__).resolve().parents[3]


@pytest.mark.parametrize("seed", range(5))
def test_rank_matches_python_control(seed):
    rng = np.random.default_rng(seed)
    n, m = 2 + seed % 3, 1 + seed % 2
    A, B = rng.normal(size=(n, n)), rng.normal(size=(n, m))
    if seed % 2:  # an uncontrollable pair: a state B cannot reach
        A[0, 1:], B[0, :] = 0.0, 0.0
    s = LTISystem("t", A, B) if not seed % 2 else None
    C = control.ctrb(A, B)
    want = int(np.linalg.matrix_rank(C, tol=1e-9 * max(1.0, np.abs(C).max())))
    if s is None:
        with pytest.warns(UserWarning):
            s = LTISystem("t", A, B)
    assert s.controllability_rank == want


def test_zoh_matches_python_control():
    J, L, c, K, Ke, r, dt = 0.01, 0.5, 0.1, 0.01, 0.01, 1.0, 1.0
    Ac = np.array([[0.0, 1.0, 0.0], [0.0, -c / J, K / J], [0.0, -Ke / L, -r / L]])
    Bc = np.array([[0.0, 0.0], [0.0, 1.0 / J], [1.0 / L, 0.0]])
    sysd = control.c2d(control.ss(Ac, Bc, np.eye(3), np.zeros((3, 2))), dt)
    s = dc_motor_physical(dt=dt, J=J, L=L, c=c, K=K, Ke=Ke, r=r)
    assert np.allclose(s.A, sysd.A, atol=1e-12) and np.allclose(s.B, sysd.B, atol=1e-12)


def test_presets_build_without_python_control():
    probe = (
        "import sys; from qsid_core.plant.systems import PRESETS; [f() for f in PRESETS.values()]; "
        "print('control' in sys.modules)"
    )
    r = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "False"
