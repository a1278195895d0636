"""Controllability on the docs' five plants: scale-invariant, and python-control's answer."""

import warnings
from pathlib import Path

import control
import numpy as np
import pytest

from qsid_core import LTISystem, load_system

DATA = Path(__file__).resolve().parents[3] / "docs" / "data"
PLANTS = ["servo", "pitch", "pendcart", "chain", "bus"]


@pytest.mark.parametrize("name", PLANTS)
def test_rank_agrees_with_python_control_in_any_units(name):
    s = load_system(DATA / f"{name}.toml")
    want = int(np.linalg.matrix_rank(control.ctrb(s.A, s.B)))  # numpy's default, relative tolerance
    assert want == s.n  # all five are controllable
    T = np.diag(10.0 ** np.arange(s.n))  # states in other units
    for A, B in ((s.A, s.B), (s.A, s.B * 1e3), (s.A, s.B * 1e-3), (T @ s.A @ np.linalg.inv(T), T @ s.B)):
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # no "not controllable" warning
            assert LTISystem(name, A, B).controllability_rank == want


def test_bus_at_one_newton_is_controllable_whatever_the_unit_of_force():
    """On main the absolute tolerance said rank 3 < 4 for the bus (B ~ 3e-5 per N) but 4 with B x 1000."""
    s = load_system(DATA / "bus.toml")
    assert s.controllable
    assert LTISystem("bus-kN", s.A, s.B * 1e3).controllable


def test_an_uncontrollable_pair_stays_uncontrollable_in_any_units():
    for c in (1e-8, 1.0, 1e8):
        with pytest.warns(UserWarning, match="not controllable"):
            s = LTISystem("u", [[0.5, 0.1], [0.0, 0.9]], [[c], [0.0]])
        assert s.controllability_rank == 1
