"""The data-rate floor ignores |eigenvalue| within round-off of 1."""

from pathlib import Path

import numpy as np

from qsid_core import load_system
from qsid_core.control import data_rate_bits

DATA = Path(__file__).resolve().parents[3] / "docs" / "data"


def test_undamped_masses_need_no_bits():
    A = load_system(DATA / "chain.toml").A
    assert np.abs(np.abs(np.linalg.eigvals(A)) - 1).max() < 1e-12  # on the unit circle up to round-off
    assert data_rate_bits(A) == 0.0


def test_unstable_modes_count():
    A = load_system(DATA / "pendcart.toml").A
    lam = np.abs(np.linalg.eigvals(A))
    assert data_rate_bits(A) == np.log2(lam[lam > 1 + 1e-7]).sum() > 0.05
    assert data_rate_bits(np.diag([2.0, 0.5, 1.0 + 1e-15])) == 1.0
