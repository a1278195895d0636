"""The budget study (qsid_core.studies.budget): the runs each word length buys, the errors of models identified by
the sweep's own stages, the knee, the predicted error, the loops, and bad input as one ConfigError."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from qsid_core import ConfigError, MPCConfig, SweepConfig
from qsid_core.studies import BudgetConfig, KoopmanConfig, run_budget, runs_bought
from qsid_core.studies.budget_model import lag_moment, predicted_error

BOEING = SweepConfig(system="boeing747", steps=100, realizations=3, estimator="bcls", mpc=None)


def test_runs_bought_is_the_floor_of_the_budget_over_the_cost_of_a_run():
    assert runs_bought(4e7, 100, 6, 2) == 33_333  # the numbers
    assert runs_bought(4e7, 100, 6, 16) == 4_166
    assert runs_bought(599, 100, 6, 1) == 0 and runs_bought(600, 100, 6, 1) == 1


def test_a_b_whose_budget_buys_no_run_is_a_row_not_a_crash():
    # 1800 bits: 3 runs at b = 1, 1 at b = 2 and 3, none at b = 4
    res = run_budget(BudgetConfig(1800, replace(BOEING, bits=(1, 2, 3, 4))))
    rows = {r["bits"]: r for r in res.to_dict()["rows"]}
    assert [rows[b]["trajectories"] for b in (1, 2, 3, 4)] == [3, 1, 1, 0]
    assert rows[4]["identifiable"] is False and "no run" in rows[4]["note"] and rows[4]["err_G"]["mean"] is None
    assert all(rows[b]["identifiable"] and rows[b]["err_G"]["mean"] > 0 for b in (1, 2, 3))
    assert res.b_best in (1, 2, 3)


def test_too_few_samples_to_identify_is_not_identifiable():
    # runs of 2 steps: at b = 2, 1 run gives 2 samples for 6 unknowns per row
    d = run_budget(BudgetConfig(2 * 6 * 2 * 4, replace(BOEING, bits=(1, 2), steps=2))).to_dict()
    rows = {r["bits"]: r for r in d["rows"]}
    assert rows[1]["trajectories"] == 8 and rows[1]["identifiable"]
    assert rows[2]["trajectories"] == 4 and rows[2]["identifiable"]
    d = run_budget(BudgetConfig(2 * 6 * 2 * 2, replace(BOEING, bits=(1, 2), steps=2))).to_dict()
    rows = {r["bits"]: r for r in d["rows"]}
    assert (
        rows[2]["trajectories"] == 2 and not rows[2]["identifiable"] and "fewer than the 6 unknowns" in rows[2]["note"]
    )


@pytest.mark.parametrize(
    "kw,field",
    [
        ({"total_bits": -5}, "total bits"),
        ({"total_bits": 0}, "total bits"),
        ({"total_bits": float("nan")}, "total bits"),
        ({"total_bits": 1e6 + 0.5}, "total bits"),
        ({"total_bits": 1e6, "study": "boeing747"}, "study"),
        ({"total_bits": 1e6, "study": replace(BOEING, input_bits="exact")}, "input bits"),
        ({"total_bits": 1e6, "target": 2.0}, "target"),
        ({"total_bits": 1e6, "knee": 0}, "knee"),
    ],
)
def test_bad_settings_are_one_config_error_naming_the_field(kw, field):
    with pytest.raises(ConfigError, match=field):
        BudgetConfig(**kw)


def test_a_budget_too_small_for_any_b_is_one_config_error():
    with pytest.raises(ConfigError, match="total bits: 100 bits identify nothing at any b.*at least 600 bits"):
        run_budget(BudgetConfig(100, BOEING))
    with pytest.raises(ConfigError, match="more than 100000"):
        BudgetConfig(1e12, replace(BOEING, bits=(1,))).plan()
    with pytest.raises(ConfigError, match="config must be a BudgetConfig"):
        run_budget(BOEING)  # type: ignore[arg-type]


def test_noiseless_the_knee_is_at_the_top_of_the_range():
    res = run_budget(BudgetConfig(1e6, replace(BOEING, bits=(4, 8, 12, 16))))
    errs = [r["err_G"]["mean"] for r in res.to_dict()["rows"]]
    assert errs == sorted(errs, reverse=True)  # finer words always win without noise
    assert res.b_best == res.b_knee == res.b_knee_predicted == 16


def test_the_prediction_follows_the_measured_error_with_sensor_noise():
    study = replace(BOEING, bits=(2, 4, 6, 8, 12, 16), realizations=4, noise=0.1, noise_known=True)
    d = run_budget(BudgetConfig(2e6, study)).to_dict()
    for r in d["rows"]:
        assert r["predicted_err_G"] == pytest.approx(r["err_G"]["mean"], rel=0.35), r["bits"]
        assert r["predicted_bias"] == 0.0  # BCLS with the noise known: no bias, all variance
    assert abs(d["b_knee"] - d["b_knee_predicted"]) <= 2 and 4 <= d["b_knee"] <= 8
    # LS under noise sits on its errors-in-variables floor (Theorem 1 with sigma^2) at every fine b
    ls = run_budget(BudgetConfig(2e6, replace(study, estimator="ls", bits=(8, 12, 16)))).to_dict()
    for r in ls["rows"]:
        assert r["err_G"]["mean"] == pytest.approx(r["theorem1_err_G"], rel=0.1)


def test_the_predicted_error_is_theorem_1_at_infinite_data_and_grows_like_one_over_root_t():
    Sigma = np.array([[2.0, 0.0], [0.0, 1.0 / 3.0]])
    G = np.array([[0.9, 1.0]])
    S1 = np.array([[1.8, 1.0 / 3.0], [0.0, 0.0]])
    q = np.array([0.01, 0.01])
    z = np.zeros(2)
    big, bias = predicted_error(G, Sigma, S1, q, z, z, 10**12, 100)
    limit = G @ Sigma @ np.linalg.inv(Sigma + np.diag(q))
    assert bias == pytest.approx(np.linalg.norm(limit - G) / np.linalg.norm(G)) and big == pytest.approx(bias)
    one, zero_bias = predicted_error(G, Sigma, S1, q, z, q, 10_000, 100)
    four, _ = predicted_error(G, Sigma, S1, q, z, q, 40_000, 100)
    assert zero_bias == 0.0 and one == pytest.approx(2 * four)


def test_the_lag_moment_is_the_mean_of_consecutive_products_within_runs():
    from qsid_core import get_system, simulate

    data = simulate(get_system("dc-motor"), 3, 5, 0)
    psi = np.concatenate([data.states[:, :-1], data.inputs], axis=2)
    want = sum(np.outer(psi[j, t + 1], psi[j, t]) for j in range(3) for t in range(4)) / 12
    assert np.allclose(lag_moment(data), want)


def test_realizations_have_their_own_data_and_the_loops_run_on_the_true_plant():
    study = replace(BOEING, bits=(4, 8), realizations=4, mpc=MPCConfig(steps=30))
    res = run_budget(BudgetConfig(1e6, study))
    d = res.to_dict()
    for r in d["rows"]:
        assert r["err_G"]["std"] > 0  # own data per realization: the errors differ
        assert sum(r["closed_loop_outcomes"].values()) == 4
        assert r["stabilized_fraction"] == r["closed_loop_outcomes"]["converged"] / 4
        assert r["cost_gap"] is not None and abs(r["cost_gap"]) < 0.05
    assert d["true_model_cost"] > 0 and d["b_loop"] in (4, 8, None)
    again = run_budget(BudgetConfig(1e6, study)).to_dict()
    assert again["rows"] == d["rows"]  # seeded: the same numbers every time


def test_a_nonlinear_plant_goes_through_the_nonlinear_sweeps_stages():
    from qsid_core.studies import KOOPMAN_MPC

    study = KoopmanConfig(
        system="pendulum", lifting="poly:3", estimator="bcls", bits=(3, 6), steps=50, realizations=2,
        mpc=replace(KOOPMAN_MPC, steps=60),
    )  # fmt: skip
    d = run_budget(BudgetConfig(3e5, study)).to_dict()
    assert d["nonlinear"] and d["config"]["lifting"] == "poly:3"
    rows = {r["bits"]: r for r in d["rows"]}
    assert rows[3]["trajectories"] == runs_bought(3e5, 50, 3, 3) == 666
    assert rows[6]["err_G"]["mean"] < rows[3]["err_G"]["mean"]
    assert "predicted_err_G" not in rows[3]  # Theorem 1's model is for linear plants
    assert sum(rows[3]["closed_loop_outcomes"].values()) == 2 and 0 <= rows[3]["within_radius"] <= 2
    assert rows[3]["settled_offset"] is None or rows[3]["settled_offset"]["median"] > 0


def test_a_realization_hands_each_experiment_what_it_would_compute_itself():
    from qsid_core import Experiment, get_system, simulate, theorem1_prediction
    from qsid_core.plant.data import with_sensor_noise
    from qsid_core.studies.budget_tasks import fixed_range, linear_realization, realization_seeds

    study = replace(BOEING, system=get_system("boeing747"), noise=0.1, noise_known=True)
    rows = linear_realization(study, ((2, 30), (8, 7)), 0)
    ds, dt = realization_seeds(study.data_seed, study.dither_seed, 0)
    full = simulate(study.system, 30, study.steps, ds)
    spec = fixed_range(with_sensor_noise(full, study.noise, ds), study.quantizer)
    for row, (b, runs) in zip(rows, ((2, 30), (8, 7))):
        cfg = replace(study, quantizer=spec, bits=(b,), trajectories=runs, realizations=1, data_seed=ds, dither_seed=dt)
        key = Experiment(cfg).keys.data()
        ex = Experiment(cfg, cache={key: _first(full, runs)})  # the realization's first runs, nothing else
        ident = ex.identification(b)  # the Experiment normalises its data and draws the noise itself
        assert np.array_equal(ident.A_hat[0], row["A"]) and np.array_equal(ident.B_hat[0], row["B"])
        assert np.array_equal(ident.eps, row["eps"])
        limit = theorem1_prediction(study.system.G, ex.Sigma, ident.eps, "subtractive", ex.noise_variance())
        G = study.system.G
        assert row["theorem1_err_G"] == pytest.approx(np.linalg.norm(limit - G) / np.linalg.norm(G), rel=1e-9)


def _first(data, runs):
    from qsid_core import Dataset

    return Dataset(data.states[:runs], data.inputs[:runs], data.seed, data.input_amplitude)
