"""Training runs' initial-state amplitude: x0 ~ U[-a, a]^n, in the engine and the CLI; on
the bus suspension at 1 N, small initial states let the data identify B."""

from pathlib import Path

import numpy as np
import pytest

from app.cli import build_parser
from app.cli.runner import config, system_from_args
from app.settings.command import sweep_argv
from qsid_core import ConfigError, SweepConfig, get_system, load_system
from qsid_core.plant.data import simulate

DATA = Path(__file__).resolve().parents[3] / "docs" / "data"


def test_initial_states_scale_and_nothing_else_changes():
    s = get_system("boeing747")
    one, small = simulate(s, 20, 30, seed=3), simulate(s, 20, 30, seed=3, state_amplitude=0.01)
    np.testing.assert_allclose(small.states[:, 0], 0.01 * one.states[:, 0])
    np.testing.assert_array_equal(small.inputs, one.inputs)
    assert np.abs(small.states[:, 0]).max() <= 0.01
    with pytest.raises(ConfigError, match="state amplitude"):
        SweepConfig(state_amplitude=0.0)


def test_the_flag_reaches_the_config_and_back():
    args = build_parser().parse_args(["sweep", "--state-amplitude", "0.001"])
    cfg = config(args, system_from_args(args), True)
    assert cfg.state_amplitude == 0.001
    assert "--state-amplitude=0.001" in sweep_argv(cfg)
    assert SweepConfig.from_dict(cfg.to_dict()).state_amplitude == 0.001


def test_bus_at_one_newton_is_identified_from_small_initial_states():
    from qsid_core import Experiment

    base = dict(system=load_system(DATA / "bus.toml"), bits=(14,), realizations=5, trajectories=50, steps=400)
    errs = {
        a: float(np.mean(Experiment(SweepConfig(state_amplitude=a, mpc=None, **base)).identification(14).err_B))
        for a in (1.0, 0.001)
    }
    assert errs[1.0] > 0.1 and errs[0.001] < 0.01, errs
