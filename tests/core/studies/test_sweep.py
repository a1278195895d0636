import json

import numpy as np
import pytest

from qsid_core import MPCConfig, QuantizerSpec, SummaryRow, SweepConfig, run_sweep, summary_row
from qsid_core.control.timeseries import saturated_steps
from qsid_core.studies.summary import json_clean

SMALL = dict(trajectories=10, steps=200, realizations=4)
OLD_KEYS = (
    "bits",
    "eps_x",
    "eps_u",
    "err_A",
    "err_B",
    "err_A_theory",
    "err_B_theory",
    "overload_fraction",
    "bcls_fallbacks",
    "ultimate_bound",
    "ultimate_bound_note",
    "ident_failures",
    "mpc_cost",
    "final_state_norm",
    "qp_steps",
)
NEW_KEYS = (
    "realizations",
    "effective_realizations",
    "rho",
    "ultimate_bound_realized",
    "assumptions",
    "saturated_steps",
)


def test_summary_row_is_typed_and_its_dict_keeps_old_keys_and_values():
    res = run_sweep(SweepConfig(bits="3:4", **SMALL))
    row = res.summary(4)
    assert isinstance(row, SummaryRow)
    d = row.to_dict()
    assert tuple(d)[: len(OLD_KEYS)] == OLD_KEYS and all(k in d for k in NEW_KEYS)
    ident, th = res.identification[4], res.theory[4]
    assert d["err_A"]["mean"] == pytest.approx(ident.err_A.mean()) and d["err_A_theory"] == th.err_A
    assert d["ultimate_bound"] == th.delta and d["rho"] == pytest.approx(th.bound.rho) and d["rho"] > 0
    assert d["effective_realizations"] == d["realizations"] == 4
    rb = res.realized[4]
    assert d["ultimate_bound_realized"] == {
        "median": pytest.approx(rb.median),
        "max": pytest.approx(rb.max),
        "self_consistent": rb.self_consistent,
        "informative": rb.informative,
    }
    assert d["assumptions"]["bits"] == 4 and isinstance(d["assumptions"]["notes"], list)
    assert d["saturated_steps"]["of_steps"] == 4 * res.config.mpc.steps
    # a row reads like the former dict rows (front ends written for them keep working)
    assert row["err_A"]["mean"] == d["err_A"]["mean"] and dict(row) == d
    # the plain call, as front ends make it, works without the optional parts
    bare = summary_row(3, ident, th, res.loops[4]).to_dict()
    assert bare["ultimate_bound_realized"] is None and bare["assumptions"] is None and bare["saturated_steps"] is None


def test_sweep_json_is_strict_and_has_new_config_fields():
    q = QuantizerSpec(range_mode="fixed", fixed_range=[(-3, 3)] * 3 + [(-1, 1)] * 2, guard=False)
    res = run_sweep(SweepConfig(bits="1:2", quantizer=q, input_amplitude=0.5, mpc=MPCConfig(steps=10), **SMALL))
    d = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    c = d["config"]
    assert c["input_amplitude"] == 0.5 and c["guard"] is False and c["fixed_range"][3] == [-1.0, 1.0]
    assert len(d["results"]) == 2


def test_json_clean_replaces_non_finite():
    out = json_clean(
        {
            "a": float("nan"),
            "b": [np.inf, 1.0, np.float64(2)],
            "c": np.array([np.nan, 3.0]),
            "d": np.bool_(True),
            "e": np.int64(4),
        }
    )
    assert out == {"a": None, "b": [None, 1.0, 2.0], "c": [None, 3.0], "d": True, "e": 4}
    json.dumps(out, allow_nan=False)


def test_saturated_steps_counts_inputs_on_their_bound():
    u = np.zeros((3, 5, 2))
    u[0, 1, 0] = 0.2
    u[0, 2, 1] = -0.2
    u[1, 4, 1] = 0.1999999999999
    u[2, :, :] = np.nan
    assert saturated_steps(u, [0.2, 0.2]) == (3, 2)
    assert saturated_steps(u, None) == (0, 0)


def test_small_input_bound_saturates_in_sweep():
    res = run_sweep(SweepConfig(system="boeing747", bits="8", mpc=MPCConfig(u_max=0.05, steps=20), **SMALL))
    s = res.summary(8).to_dict()["saturated_steps"]
    assert s["steps"] > 0 and s["loops"] == 4


def test_no_dither_has_one_effective_realization():
    res = run_sweep(SweepConfig(bits="4", quantizer=QuantizerSpec(dither="none"), mpc=None, **SMALL))
    d = res.summary(4).to_dict()
    assert d["realizations"] == 4 and d["effective_realizations"] == 1
    assert len(set(res.identification[4].err_A.tolist())) == 1
    assert not d["assumptions"]["subtractive_dither"] and not d["assumptions"]["bcls_holds"]


def test_input_amplitude_scales_inputs_and_is_cached_separately():
    from qsid_core import Experiment

    cache: dict = {}
    a = Experiment(SweepConfig(bits="4", mpc=None, **SMALL), cache=cache)
    b = Experiment(SweepConfig(bits="4", mpc=None, input_amplitude=0.25, **SMALL), cache=cache)
    np.testing.assert_allclose(b.data.inputs, 0.25 * a.data.inputs)
    assert np.abs(b.data.inputs).max() <= 0.25
    assert b.identification(4) is not a.identification(4)
    with pytest.raises(ValueError, match="input amplitude"):
        SweepConfig(input_amplitude=0.0)


def test_summarize_matches_sweep_row():
    from qsid_core import Experiment
    from qsid_core.studies.sweep import summarize

    cfg = SweepConfig(bits="4", **SMALL)
    res = run_sweep(cfg)
    row = summarize(Experiment(cfg), 4)
    assert row.to_dict() == res.summary(4).to_dict()


def test_result_json_has_its_format_and_format_1_files_load_with_the_renamed_key(tmp_path):
    from qsid_core import ConfigError, load_result
    from qsid_core.studies import RESULT_FORMAT

    res = run_sweep(SweepConfig(bits=(3,), mpc=MPCConfig(steps=10, u_max=(0.2,)), **SMALL))
    d = json.loads(json.dumps(res.to_dict()))
    assert d["result_format"] == RESULT_FORMAT == 2
    row = d["results"][0]
    assert "osqp_steps" not in row and row["qp_steps"] == res.loops[3].qp_steps
    old = json.loads(json.dumps(d))  # as qsid wrote it before the key was renamed
    del old["result_format"]
    old["results"][0] = {("osqp_steps" if k == "qp_steps" else k): v for k, v in row.items()}
    (tmp_path / "v1.json").write_text(json.dumps(old))
    back = load_result(tmp_path / "v1.json")
    assert list(back.summary(3)) == list(row) and back.summary(3)["qp_steps"] == row["qp_steps"]
    assert back.to_dict()["results"] == d["results"]
    newer = dict(d, result_format=RESULT_FORMAT + 1)
    (tmp_path / "v3.json").write_text(json.dumps(newer))
    with pytest.raises(ConfigError, match="result_format 3"):
        load_result(tmp_path / "v3.json")


@pytest.mark.parametrize("estimator", ["ls", "bcls"])
def test_a_sweep_with_an_executor_overlaps_its_stages_and_equals_the_inline_sweep(estimator):
    # with an executor, the moments and the closed loops run beside Theorem 1, the overload effects, the bounds
    # and the assumptions (a helper thread submits them); every number must be the inline sweep's, to the last digit
    from concurrent.futures import ThreadPoolExecutor

    cfg = SweepConfig(bits="1:6", estimator=estimator, quantizer=QuantizerSpec(guard=False), **SMALL)
    a = run_sweep(cfg).to_dict()
    with ThreadPoolExecutor(2) as pool:
        b = run_sweep(cfg, executor=pool).to_dict()
    for d in (a, b):
        d.pop("timing_s")
    assert json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)
    effects = [r["assumptions"]["overload_effect_A"] for r in a["results"]]
    assert effects[0] > 1e-3  # without the guard band b = 1 clips the data: its effect was computed
