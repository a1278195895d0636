"""A researcher's what-ifs: word length per input channel, sensor noise, studies saved and re-run, notebook views."""

import json
import re
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from qsid_core import (
    ConfigError,
    MPCConfig,
    QuantizerSpec,
    SweepConfig,
    __version__,
    load_result,
    prepare,
    quantized_moments,
    run_sweep,
    simulate,
)
from qsid_core.plant.systems import boeing747

SMALL = dict(system="boeing747", trajectories=20, steps=300, realizations=2)
ROOT = Path(__file__).resolve().parents[3]


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


# ----- word length per channel ------------------------------------------------------------------
def test_exact_inputs_give_eps_u_zero_and_a_smaller_B_error_through_the_cli(capsys):
    base = ["sweep", "--system", "boeing747", "--bits", "4", "--realizations", "2", "--no-mpc", "--json"]
    code, out, err = _run(capsys, *base)
    assert code == 0, err
    same = json.loads(out)
    code, out, err = _run(capsys, *base, "--input-bits", "exact")
    assert code == 0, err
    ex = json.loads(out)
    (r0,), (r1,) = same["results"], ex["results"]
    assert all(e > 0 for e in r0["eps_u"]) and r1["eps_u"] == [0.0, 0.0]
    assert r1["eps_x"] == r0["eps_x"]  # the states are quantized as before
    assert r1["err_B"]["mean"] < 0.5 * r0["err_B"]["mean"]
    assert ex["config"]["input_bits"] == "exact"


def test_input_bits_forms_and_per_channel_eps():
    res = run_sweep(SweepConfig(bits=(4,), input_bits=(8, "exact"), mpc=None, **SMALL))
    eps = res.identification[4].eps
    lo, hi = res.ranges["lo"], res.ranges["hi"]
    assert eps[4] == pytest.approx((hi[4] - lo[4]) / (2**8 - 1)) and eps[5] == 0.0
    assert eps[0] == pytest.approx((hi[0] - lo[0]) / (2**4 - 1))
    assert SweepConfig(input_bits="12").input_bits == 12 and SweepConfig(input_bits="same").input_bits is None


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["--input-bits", "3,4,5"], "input_bits has 3 entries; the system has 2"),
        (["--input-bits", "0"], "input bits must be"),
        (["--input-bits", "many"], "input bits must be"),
        (["--noise", "1,2"], "give 1 or 4 values"),
        (["--noise=-1"], "noise must be in"),
        (["--noise", "abc"], "noise must be one standard deviation"),
    ],
)
def test_bad_what_if_flags_are_one_line_errors(capsys, argv, needle):
    code, out, err = _run(
        capsys,
        "sweep",
        "--system",
        "boeing747",
        "--bits",
        "4",
        "--realizations",
        "1",
        "--trajectories",
        "3",
        "--steps",
        "50",
        "--no-mpc",
        *argv,
    )
    assert code == 2 and needle in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_exact_input_channel_in_the_fused_moments_equals_the_unquantized_columns():
    data = simulate(boeing747(), 7, 2500, seed=3)
    spec = QuantizerSpec()
    prep = prepare(data, spec)
    for engine in ("numpy", "auto"):
        mo = quantized_moments(prep, [20], spec, np.random.default_rng(1), engine=engine, input_bits="exact")[0]
        # inputs exact: their block of Psi Psi^T is the unquantized one
        np.testing.assert_allclose(mo.PP[4:, 4:], prep.exact.PP[4:, 4:], rtol=1e-12)
        full = quantized_moments(prep, [20], spec, np.random.default_rng(1), engine=engine)[0]
        np.testing.assert_array_equal(mo.PP[:4, :4], full.PP[:4, :4])  # states: the same draws, same numbers


def test_state_bits_fix_or_exempt_single_states_and_reach_the_json(capsys):
    res = run_sweep(SweepConfig(bits=(3, 6), state_bits="b,b,12,exact", mpc=None, **SMALL))
    for b in (3, 6):
        eps, lo, hi = res.identification[b].eps, res.ranges["lo"], res.ranges["hi"]
        assert eps[0] == pytest.approx((hi[0] - lo[0]) / (2**b - 1))
        assert eps[2] == pytest.approx((hi[2] - lo[2]) / (2**12 - 1)) and eps[3] == 0.0
    assert res.to_dict()["config"]["state_bits"] == ["b", "b", 12, "exact"]
    assert SweepConfig(state_bits="exact").state_bits == ("exact",)
    exact = run_sweep(SweepConfig(bits=(3,), state_bits="exact", input_bits="exact", mpc=None, **SMALL))
    assert exact.identification[3].err_A.max() < 1e-9  # nothing quantized, noise-free data: the exact model
    code, out, err = _run(
        capsys,
        "sweep",
        "--system",
        "boeing747",
        "--bits",
        "3",
        "--realizations",
        "1",
        "--trajectories",
        "3",
        "--steps",
        "50",
        "--no-mpc",
        "--state-bits",
        "b,b",
    )
    assert code == 2 and "state_bits has 2 entries; the system has 4" in err


# ----- sensor noise ------------------------------------------------------------------------------
def test_sensor_noise_biases_ls_and_bcls_removes_it_only_when_known():
    kw = dict(bits=(8,), noise=0.05, mpc=None, estimator="bcls", **SMALL)
    clean = run_sweep(SweepConfig(**{**kw, "noise": 0.0}))
    unknown = run_sweep(SweepConfig(**kw))
    known = run_sweep(SweepConfig(**kw, noise_known=True))
    e = lambda r: float(r.identification[8].err_A.mean())  # noqa: E731
    assert e(unknown) > 3 * e(known) and e(unknown) > 3 * e(clean)
    d = known.to_dict()
    assert d["config"]["noise"] == [0.05] and d["config"]["noise_known"] is True and "sigma^2" in d["bcls"]["D"]
    assert unknown.assumptions[8].bcls_holds is False and unknown.assumptions[8].sensor_noise_known is False
    assert known.assumptions[8].sensor_noise_known is True and clean.assumptions[8].sensor_noise_known is True
    # Theorem 1's line includes the noise (the LS limit), whatever BCLS knows
    assert unknown.theory[8].err_A > 3 * clean.theory[8].err_A


def test_noise_is_seeded_by_the_data_seed():
    a = run_sweep(SweepConfig(bits=(6,), noise=0.02, mpc=None, **SMALL))
    b = run_sweep(SweepConfig(bits=(6,), noise=0.02, mpc=None, **SMALL))
    c = run_sweep(SweepConfig(bits=(6,), noise=0.02, mpc=None, data_seed=5, **SMALL))
    np.testing.assert_array_equal(a.identification[6].A_hat, b.identification[6].A_hat)
    assert not np.array_equal(a.identification[6].A_hat, c.identification[6].A_hat)


# ----- studies that last -------------------------------------------------------------------------
def test_json_carries_the_full_config_and_the_version():
    q = QuantizerSpec(dither="tpdf", range_mode="fixed", fixed_range=(-20, 20))
    res = run_sweep(
        SweepConfig(bits=(3, 4), quantizer=q, input_bits=10, mpc=MPCConfig(steps=5, Qf=(1.0,) * 4), **SMALL)
    )
    d = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    c = d["config"]
    s = boeing747()
    assert d["qsid_version"] == __version__
    assert np.array_equal(c["system_definition"]["A"], s.A) and np.array_equal(c["system_definition"]["B"], s.B)
    for k in ("x0", "Q", "R"):
        assert np.array_equal(c["system_definition"][k], getattr(s, k))
    assert c["mpc_settings"]["Qf"] == [1.0] * 4 and c["mpc_settings"]["steps"] == 5
    assert c["dither"] == "tpdf" and c["input_bits"] == 10 and c["data_seed"] == 0 and c["dither_seed"] == 1
    assert len(d["ranges"]["lo"]) == 6
    assert SweepConfig.from_dict(d).to_dict() == res.config.to_dict()


def test_version_is_pyprojects_and_qsid_version_prints_it(capsys):
    text = (ROOT / "pyproject.toml").read_text()
    # the version is written once, in qsid_core/version.py; pyproject reads it from there
    assert not re.search(r'^version = "', text, re.M)
    assert re.search(r'^dynamic = \["version"\]', text, re.M)
    assert 'version = { attr = "qsid_core.version.__version__" }' in text
    code, out, _ = _run(capsys, "--version")
    assert code == 0 and out.strip() == f"qsid {__version__}"


def test_a_saved_json_reruns_to_identical_numbers_with_config(capsys, tmp_path):
    saved = tmp_path / "study.json"
    argv = [
        "sweep",
        "--system",
        "boeing747",
        "--bits",
        "3,5",
        "--realizations",
        "2",
        "--trajectories",
        "10",
        "--steps",
        "200",
        "--dither",
        "tpdf",
        "--input-bits",
        "exact",
        "--noise",
        "0.01",
        "--mpc-steps",
        "5",
        "--seed",
        "4",
        "-q",
        "--out",
        str(saved),
    ]
    code, _, err = _run(capsys, *argv)
    assert code == 0, err
    code, out, err = _run(capsys, "sweep", "--config", str(saved), "--json", "-q")
    assert code == 0, err
    a, b = json.loads(saved.read_text()), json.loads(out)
    a.pop("timing_s"), b.pop("timing_s")
    assert a == b
    # a flag given with a non-default value overrides the file
    code, out, err = _run(capsys, "sweep", "--config", str(saved), "--bits", "4", "--json", "-q", "--no-mpc")
    assert code == 0, err
    c = json.loads(out)
    assert c["config"]["bits"] == [4] and c["config"]["dither"] == "tpdf" and c["config"]["mpc"] is None
    code, out, err = _run(capsys, "sweep", "--config", str(saved), "--horizon", "3", "--json", "-q")
    assert code == 0, err
    c = json.loads(out)["config"]
    assert c["mpc"]["horizon"] == 3 and c["mpc"]["steps"] == 5 and c["noise"] == [0.01]
    code, _, err = _run(capsys, "sweep", "--config", str(saved), "--system", "boeing747", "-q")
    assert code == 2 and "the system comes from the file" in err


def test_config_from_toml_and_bad_files(capsys, tmp_path):
    t = tmp_path / "s.toml"
    t.write_text(
        'system = "dc-motor"\nbits = "2:3"\nrealizations = 2\ntrajectories = 5\nsteps = 100\n'
        'dither = "rpdf"\nestimator = "bcls"\n[mpc]\nsteps = 3\nhorizon = 4\n'
    )
    code, out, err = _run(capsys, "sweep", "--config", str(t), "--json", "-q")
    assert code == 0, err
    d = json.loads(out)
    assert d["config"]["bits"] == [2, 3] and d["config"]["mpc"]["horizon"] == 4 and d["bcls"]["applicable"] is False
    bad = tmp_path / "bad.toml"
    bad.write_text('bits = "2:3"\ncolour = "red"\n')
    code, _, err = _run(capsys, "sweep", "--config", str(bad), "-q")
    assert code == 2 and "unknown setting(s) ['colour']" in err
    code, _, err = _run(capsys, "sweep", "--config", str(tmp_path / "missing.json"), "-q")
    assert code == 2 and "cannot read" in err
    (tmp_path / "x.json").write_text("{not json")
    code, _, err = _run(capsys, "sweep", "--config", str(tmp_path / "x.json"), "-q")
    assert code == 2 and "not valid JSON" in err


def test_load_result_reads_back_a_sweep_result(tmp_path):
    res = run_sweep(SweepConfig(bits=(3, 4), mpc=MPCConfig(steps=5), **SMALL))
    p = tmp_path / "r.json"
    p.write_text(json.dumps(res.to_dict()))
    back = load_result(p)
    assert back.config.to_dict() == res.config.to_dict() and back.bits == (3, 4)
    assert back.summary(4)["err_A"] == res.summary(4).to_dict()["err_A"]
    a, b = back.to_dict(), res.to_dict()
    assert a == b
    rerun = run_sweep(back.config)
    np.testing.assert_array_equal(rerun.identification[3].err_A, res.identification[3].err_A)
    (tmp_path / "old.json").write_text(json.dumps({"config": {"bits": [3]}, "results": []}))
    with pytest.raises(ConfigError, match="without the full configuration"):
        load_result(tmp_path / "old.json")
    with pytest.raises(ConfigError, match="cannot read"):
        load_result(tmp_path / "nope.json")


# ----- notebooks ---------------------------------------------------------------------------------
def test_repr_is_short_html_is_a_table_and_to_frame_has_one_row_per_b():
    res = run_sweep(SweepConfig(bits="1:16", mpc=None, system="dc-motor", trajectories=10, steps=100, realizations=2))
    r = repr(res)
    assert len(r) <= 2000 and "dc-motor" in r and "..." in r
    h = res._repr_html_()
    assert h.count("<tr>") == 17 and "<table>" in h
    cols = res.to_frame(pandas=False)
    assert cols["b"] == list(range(1, 17)) and len(cols["err_A_mean"]) == 16
    pd = pytest.importorskip("pandas")
    f = res.to_frame()
    assert isinstance(f, pd.DataFrame) and len(f) == 16 and f["estimator"].eq("ls").all()


def test_unswept_b_is_a_clear_error():
    res = run_sweep(SweepConfig(bits=(2, 3), mpc=None, system="dc-motor", trajectories=5, steps=50, realizations=1))
    with pytest.raises(ConfigError, match=r"b = 7 was not swept; this result has b = 2, 3"):
        res.summary(7)
