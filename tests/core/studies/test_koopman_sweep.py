"""The nonlinear word-length sweep: rows, references, reports."""

from __future__ import annotations

import numpy as np
import pytest

from qsid_core.errors import ConfigError
from qsid_core.plant import NonlinearSystem
from qsid_core.studies import NO_CERTIFICATES, KoopmanConfig, run_koopman_sweep


def test_de_biased_edmd_beats_ls_against_the_unquantized_edmd_and_the_rows_are_complete():
    base = dict(system="duffing", bits=(3, 6), trajectories=300, steps=60, realizations=3, mpc=None)
    ls = run_koopman_sweep(KoopmanConfig(estimator="ls", **base)).to_dict()
    bc = run_koopman_sweep(KoopmanConfig(estimator="bcls", **base)).to_dict()
    assert ls["certificates"] == NO_CERTIFICATES and ls["config"]["features"] == 10
    for d in (ls, bc):
        assert [r["bits"] for r in d["results"]] == [3, 6]
        assert all(r["stabilized_fraction"] is None for r in d["results"])  # no loops asked for
    # at b = 3 LS is biased (the Gram of x~ has the eps^2/12 terms), the de-biased estimate is not
    assert bc["results"][0]["err_G"]["mean"] < 0.2 * ls["results"][0]["err_G"]["mean"]
    assert ls["results"][1]["err_G"]["mean"] < ls["results"][0]["err_G"]["mean"]
    assert ls["reference"]["prediction_error"] == bc["reference"]["prediction_error"]  # same data, same reference


def test_a_custom_plant_and_its_runs_that_leave_the_box_are_reported():
    def f(x, u):  # a stable linear oscillator plus an x1^2 term that makes some starts blow up
        return np.stack([x[:, 1], -x[:, 0] - 0.5 * x[:, 1] + 0.6 * x[:, 0] ** 2 + u[:, 0]], axis=1)

    plant = NonlinearSystem("custom", f, 2, 1, x0=(0.5, 0.0), amplitude=2.0, box=20.0)
    r = run_koopman_sweep(
        KoopmanConfig(system=plant, lifting="poly:2", bits=(6,), trajectories=200, steps=80, realizations=2)
    )
    d = r.to_dict()
    assert d["system"] == "custom" and 0 < d["data"]["runs_used"] < 200
    assert d["data"]["left_box"].startswith(f"{200 - d['data']['runs_used']} of 200 runs left the sane box")
    assert sum(d["results"][0]["closed_loop_outcomes"].values()) == 2


def test_bad_settings_name_the_field():
    with pytest.raises(ConfigError, match="estimator"):
        KoopmanConfig(estimator="tls")
    with pytest.raises(ConfigError, match="bits"):
        KoopmanConfig(bits=())
    with pytest.raises(ConfigError, match="lifting"):
        KoopmanConfig(lifting="poly:0").dictionary()


def test_the_amplitudes_and_the_box_reach_the_plant_and_the_data():
    from qsid_core.studies import KoopmanConfig

    cfg = KoopmanConfig(state_amplitude=0.5, box=7.0, input_amplitude=0.25)
    s = cfg.plant()
    assert (s.amplitude, s.box) == (0.5, 7.0) and KoopmanConfig().plant().amplitude == 2.0
    small = dict(trajectories=30, steps=5, realizations=1, bits=(6,), mpc=None, lifting="poly:2")
    d = run_koopman_sweep(KoopmanConfig(state_amplitude=0.5, input_amplitude=0.25, box=7.0, **small)).to_dict()
    assert (d["config"]["state_amplitude"], d["config"]["input_amplitude"], d["config"]["box"]) == (0.5, 0.25, 7.0)
    wide = run_koopman_sweep(KoopmanConfig(**small)).to_dict()
    assert wide["config"]["state_amplitude"] == 2.0 and wide["results"][0]["eps_x"] != d["results"][0]["eps_x"]
    # the quantizer's per-channel range follows the data: smaller amplitudes give finer cells
    assert d["results"][0]["eps_u"][0] < 0.5 * wide["results"][0]["eps_u"][0]


@pytest.mark.parametrize(
    "kw,match",
    [
        ({"radius": 0.0}, "radius"),
        ({"state_amplitude": -1.0}, "state amplitude"),
        ({"box": float("nan")}, "box"),
        ({"input_amplitude": 0}, "input amplitude"),
        ({"prediction_horizon": 0}, "prediction horizon"),
        ({"prediction_horizon": 41}, "prediction horizon"),  # past the held-out runs' 40 samples
        ({"prediction_horizon": 2.5}, "prediction horizon"),
        ({"prediction_horizon": True}, "prediction horizon"),
    ],
)
def test_bad_nonlinear_settings_name_the_field(kw, match):
    from qsid_core import ConfigError
    from qsid_core.studies import KoopmanConfig

    with pytest.raises(ConfigError, match=match):
        KoopmanConfig(**kw)


def test_an_mpc_setting_the_koopman_loops_do_not_use_is_refused_not_ignored():
    from qsid_core import ConfigError, MPCConfig
    from qsid_core.studies import KoopmanConfig

    with pytest.raises(ConfigError, match="mpc.disturbance: the Koopman MPC does not use it"):
        KoopmanConfig(mpc=MPCConfig(disturbance=0.1))
    KoopmanConfig(mpc=MPCConfig(horizon=5, Qf=(1.0, 1.0)))  # the ones it uses are fine


def test_the_prediction_horizon_reaches_both_paths_and_longer_predictions_err_more():
    from qsid_core.studies import KoopmanExperiment

    small = dict(trajectories=40, steps=50, realizations=2, bits=(3, 8), mpc=None, lifting="poly:3")
    out = {}
    for h in (1, 5, 40):
        cfg = KoopmanConfig(prediction_horizon=h, **small)
        d = run_koopman_sweep(cfg).to_dict()
        assert d["config"]["held_out"] == {"runs": 50, "steps": 40, "horizon": h}
        staged = KoopmanExperiment(cfg)  # the dashboard's staged path gives the command line's numbers
        assert staged.horizon == h and staged.reference()[1] == d["reference"]["prediction_error"]
        for r in d["results"]:
            assert staged.row(r["bits"], "ls")["prediction_error"] == r["prediction_error"]
        out[h] = d
    ref = {h: d["reference"]["prediction_error"] for h, d in out.items()}
    assert ref[1] < ref[5] < ref[40]  # an inexact model drifts from the true plant the further it predicts
    b3 = {h: d["results"][0]["prediction_error"]["mean"] for h, d in out.items()}
    assert b3[1] < b3[40]


def test_run_sweep_chooses_the_nonlinear_path_by_the_config():
    """One entry for both plant kinds: ``run_sweep`` of a KoopmanConfig is the nonlinear sweep, row for row."""
    from qsid_core.studies import KoopmanResult, run_sweep

    cfg = KoopmanConfig(system="duffing", bits=(4,), trajectories=100, steps=40, realizations=2, mpc=None)
    via, direct = run_sweep(cfg), run_koopman_sweep(cfg)
    assert isinstance(via, KoopmanResult)
    assert via.rows == direct.rows and via.reference_prediction_error == direct.reference_prediction_error


def test_a_nonlinear_study_runs_the_sweep_on_its_own_stages_and_cache():
    """``Study.run`` of a KoopmanConfig is ``run_koopman_sweep`` over the study's KoopmanExperiment: its rows are the
    staged rows, and what the sweep computed stays in the study's cache for the frames."""
    from qsid_core import Study
    from qsid_core.studies import Experiment, SweepConfig, run_sweep

    cfg = KoopmanConfig(system="duffing", bits=(3, 6), trajectories=80, steps=40, realizations=2, mpc=None)
    study = Study(cfg, cache={})
    res = study.run()
    assert res.rows == run_koopman_sweep(cfg).rows
    ex = study.experiment
    assert len(ex.cache) > 0 and ex.cached_loops(3, "ls") is None  # no MPC: no loops
    keys = set(ex.cache)
    assert ex.row(6, "ls") == res.rows[1] and set(ex.cache) == keys  # served from the cache, nothing recomputed
    with pytest.raises(ConfigError, match="experiment"):
        run_sweep(cfg, experiment=Experiment(SweepConfig(trajectories=5, steps=20, realizations=1, bits=(4,))))
