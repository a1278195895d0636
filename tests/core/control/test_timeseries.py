import numpy as np
import pytest

from qsid_core import Experiment, MPCConfig, SweepConfig
from qsid_core.control.timeseries import time_series

SMALL = dict(trajectories=10, steps=200, realizations=4)


def test_time_series_of_saturating_loops():
    cfg = SweepConfig(system="boeing747", bits=(8,), mpc=MPCConfig(u_max=0.05, steps=30), **SMALL)
    ex = Experiment(cfg)
    lp = ex.closed_loops(8)
    w = cfg.mpc.resolve(ex.system)
    ts = time_series(lp, w.x0, w.u_max)
    assert ts.states.shape == (4, 31, 4) and ts.inputs.shape == (4, 30, 2) and ts.t.tolist() == list(range(31))
    assert ts.saturated_steps == int(ts.saturated.sum()) > 0 and ts.saturated_loops == 4
    assert np.all(np.abs(ts.inputs) <= 0.05 * (1 + 1e-6))
    np.testing.assert_allclose(ts.state_mean, lp.states.mean(axis=0))
    np.testing.assert_allclose(ts.norms[:, 0], np.linalg.norm(w.x0))


def test_converged_norms_are_floored_not_1e_minus_48():
    ex = Experiment(SweepConfig(system="dc-motor", bits=(16,), mpc=MPCConfig(steps=50), **SMALL))
    lp = ex.closed_loops(16)
    ts = time_series(lp, ex.system.x0)
    assert ts.norms.min() < 1e-30  # the raw loop converges to floating-point noise
    assert ts.norms_display.min() == pytest.approx(1e-12 * np.linalg.norm(ex.system.x0))
    assert ts.converged[:, -1].all() and not ts.converged[:, 0].any()
    assert ts.saturated_steps == 0 and ts.u_max is None


def test_failed_loops_left_out_of_the_band():
    ex = Experiment(SweepConfig(system="dc-motor", bits=(4,), mpc=MPCConfig(steps=5), **SMALL))
    lp = ex.closed_loops(4)
    lp.failure[0] = "dare"
    lp.states[0, 2:] = np.nan
    ts = time_series(lp, ex.system.x0)
    assert ts.ok.tolist() == [False, True, True, True]
    np.testing.assert_allclose(ts.state_mean, lp.states[1:].mean(axis=0))
