import numpy as np
import pytest

from qsid_core import ConfigError, DataOverflowError, LTISystem, simulate
from qsid_core.plant.systems import dc_motor


def test_shapes_ranges_and_dynamics():
    s = dc_motor()
    d = simulate(s, 7, 50, seed=3)
    assert d.states.shape == (7, 51, 3) and d.inputs.shape == (7, 50, 2)
    assert np.all(np.abs(d.states[:, 0]) <= 1) and np.all(np.abs(d.inputs) <= 1)
    np.testing.assert_allclose(d.states[:, 1:], d.states[:, :-1] @ s.A.T + d.inputs @ s.B.T, atol=1e-9)
    Psi, Xp = d.matrices()
    assert Psi.shape == (5, 350) and Xp.shape == (3, 350) and d.T == 350


def test_seeded_and_reproducible():
    s = dc_motor()
    a, b, c = simulate(s, 3, 10, seed=1), simulate(s, 3, 10, seed=1), simulate(s, 3, 10, seed=2)
    np.testing.assert_array_equal(a.states, b.states)
    assert not np.array_equal(a.states, c.states)


def test_overflow_is_a_clear_error():
    unstable = LTISystem("unstable", [[3.0]], [[1.0]])
    with pytest.raises(DataOverflowError, match="spectral radius"):
        simulate(unstable, 2, 100)


@pytest.mark.parametrize("traj, steps", [(0, 10), (5, 0), (-1, 10), (2.5, 10), (1, 2)])
def test_bad_sizes(traj, steps):
    with pytest.raises(ConfigError):
        simulate(dc_motor(), traj, steps)
