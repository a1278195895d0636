"""The ``qsid`` command line: listing, sweeps (JSON and table), reproduce, errors, custom systems."""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from app.cli import main

ROOT = Path(__file__).resolve().parents[2]
TINY = ["--trajectories", "5", "--steps", "100", "--realizations", "3", "--bits", "2:4"]


def _strict_json(text: str):
    """json.loads that rejects NaN/Infinity (they are not JSON)."""

    def bad(c):
        raise AssertionError(f"non-JSON constant {c} in output")

    return json.loads(text, parse_constant=bad)


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_systems_lists_presets(capsys):
    code, out, err = _run(capsys, "systems")
    assert code == 0 and err == ""
    lines = out.splitlines()
    assert lines[0].split()[:3] == ["name", "n", "m"]
    assert any(re.match(r"dc-motor\s+3\s+2\s+DC motor", ln) for ln in lines)
    assert any(re.match(r"boeing747\s+4\s+2\s+Boeing 747", ln) for ln in lines)

    code, out, _ = _run(capsys, "systems", "--json")
    items = {d["name"]: d for d in _strict_json(out)}
    assert code == 0 and items["boeing747"]["n"] == 4 and items["dc-motor"]["m"] == 2


def test_sweep_json_has_every_key_with_the_right_types(capsys):
    code, out, err = _run(capsys, "sweep", *TINY, "--json")
    assert code == 0
    d = _strict_json(out)  # stdout is exactly one JSON object: no progress mixed in
    assert "MPC closed loops" in err and "qsid:" in err  # progress went to stderr
    for key in ("results", "mpc_cost_true_model", "slope_A", "slope_B", "timing_s", "config", "system"):
        assert key in d
    assert d["system"] == "dc-motor" and d["config"]["bits"] == [2, 3, 4]
    assert isinstance(d["slope_A"], float) and isinstance(d["slope_B"], float)
    assert isinstance(d["mpc_cost_true_model"], float) and d["timing_s"]["total"] >= 0
    assert [r["bits"] for r in d["results"]] == [2, 3, 4]
    for r in d["results"]:
        assert len(r["eps_x"]) == 3 and len(r["eps_u"]) == 2
        assert all(isinstance(e, float) and e > 0 for e in r["eps_x"] + r["eps_u"])
        for k in ("err_A", "err_B"):
            assert set(r[k]) >= {"mean", "std"} and isinstance(r[k]["mean"], float)
        for k in ("err_A_theory", "err_B_theory", "overload_fraction", "ultimate_bound"):
            assert isinstance(r[k], float)
        assert 0.0 <= r["overload_fraction"] <= 1.0
        assert isinstance(r["mpc_cost"]["mean"], float) and isinstance(r["mpc_cost"]["std"], float)
        assert isinstance(r["mpc_cost"]["failed"], int)
        assert set(r["final_state_norm"]) == {"mean", "max"}


def test_sweep_quiet_json_has_empty_stderr_and_out_file(capsys, tmp_path):
    target = tmp_path / "sub" / "sweep.json"
    code, out, err = _run(capsys, "sweep", *TINY, "--no-mpc", "--json", "--quiet", "--out", str(target))
    assert code == 0 and err == ""
    assert _strict_json(out) == _strict_json(target.read_text())


def test_sweep_table_mode(capsys):
    code, out, _ = _run(capsys, "sweep", *TINY, "-q")
    assert code == 0
    lines = out.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.lstrip().startswith("b "))
    assert "err_A" in lines[head] and "MPC cost" in lines[head] and "overload" in lines[head]
    body = lines[head + 2 : head + 5]
    assert [ln.split()[0] for ln in body] == ["2", "3", "4"]
    assert all("+/-" in ln and "%" in ln and "(0)" in ln for ln in body)
    assert "slope" in lines[head + 5] and "true-model MPC cost" in lines[head + 5] and "total" in lines[head + 5]


def test_no_mpc_gives_null_cost(capsys):
    code, out, _ = _run(capsys, "sweep", *TINY, "--no-mpc", "--json", "-q")
    d = _strict_json(out)
    assert code == 0 and d["config"]["mpc"] is None and d["mpc_cost_true_model"] is None
    assert all(r["mpc_cost"] is None and r["final_state_norm"] is None for r in d["results"])
    code, out, _ = _run(capsys, "sweep", *TINY, "--no-mpc", "-q")
    assert code == 0 and "MPC off" in out


def test_options_reach_the_config(capsys):
    code, out, _ = _run(
        capsys,
        "sweep",
        *TINY[:-2],
        "--bits",
        "2:6:2",
        "--guard",
        "--dither",
        "none",
        "--estimator",
        "bcls",
        "--horizon",
        "5",
        "--mpc-steps",
        "7",
        "--u-max",
        "2,3",
        "--seed",
        "4",
        "--theta",
        "0.3",
        "--rho",
        "2",
        "--json",
        "-q",
    )
    assert code == 0
    c = _strict_json(out)["config"]
    assert c["bits"] == [2, 4, 6] and c["range"] == "per-channel" and c["guard"] is True and c["dither"] == "none"
    assert c["estimator"] == "bcls"
    assert {k: c["mpc"][k] for k in ("horizon", "steps", "u_max")} == {"horizon": 5, "steps": 7, "u_max": [2.0, 3.0]}
    assert c["data_seed"] == 4 and c["dither_seed"] == 4 and c["theta"] == 0.3 and c["rho"] == 2.0
    code, out, _ = _run(capsys, "sweep", *TINY, "--range", "shared", "--no-mpc", "--json", "-q")
    d = _strict_json(out)
    assert code == 0 and d["config"]["range"] == "shared"
    eps = d["results"][0]["eps_x"] + d["results"][0]["eps_u"]
    assert max(eps) == pytest.approx(min(eps))  # one cell width for every channel


def test_engine_error_is_one_line(capsys, tmp_path):
    # an unstable custom system overflows while simulating: a DataOverflowError from the engine
    f = tmp_path / "unstable.toml"
    f.write_text("A = [[3.0, 0.0], [0.0, 0.5]]\nB = [[1.0], [1.0]]\n")
    code, out, err = _run(
        capsys,
        "sweep",
        "--system",
        str(f),
        "--trajectories",
        "2",
        "--steps",
        "200",
        "--realizations",
        "2",
        "--bits",
        "4",
        "--no-mpc",
        "-q",
    )
    assert code == 2 and out == "" and err.count("\n") == 1
    assert err.startswith("qsid: error: ") and "spectral radius" in err


def test_singular_identification_is_counted_not_fatal(capsys):
    # no dither + one shared range + 2 bits: every input sample lands in the same cell -> singular Gram matrix
    code, out, err = _run(
        capsys, "sweep", *TINY[:-2], "--bits", "2", "--range", "shared", "--dither", "none", "--json", "-q"
    )
    assert code == 0
    row = _strict_json(out)["results"][0]
    # every one of the 3 realizations fails to identify; each is a failed closed loop of kind "ident", no cost
    assert row["ident_failures"] == 3
    assert row["mpc_cost"] == {"mean": None, "std": None, "failed": 3, "failures": {"ident": 3}, "mean_bounded": None}


def test_seed_and_workers_reproducible(capsys):
    def results(*extra):
        code, out, _ = _run(capsys, "sweep", *TINY, "--no-mpc", "--json", "-q", *extra)
        assert code == 0
        return _strict_json(out)["results"]

    one = results("--seed", "3")
    assert results("--seed", "3", "--workers", "2") == one  # ProcessPoolExecutor gives the same numbers
    assert results("--seed", "5") != one


def test_bits_step_form(capsys):
    code, out, _ = _run(capsys, "sweep", *TINY[:-2], "--bits", "2:6:2", "--no-mpc", "--json", "-q")
    assert code == 0 and [r["bits"] for r in _strict_json(out)["results"]] == [2, 4, 6]
    code, _, err = _run(capsys, "sweep", "--bits", "2:6:0")
    assert code == 2 and "step" in err


def test_reproduce_writes_offline_panels(capsys, tmp_path):
    out_dir = tmp_path / "fig"
    # bits 2:3 leave b = 4 and 6 of the phase portraits to compute separately
    code, out, err = _run(
        capsys, "reproduce", "--system", "boeing747", "--out", str(out_dir), *TINY[:-2], "--bits", "2:3"
    )
    assert code == 0, err
    panels = ["a_error_A", "b_error_B", "c_mpc_cost", "d_phase_b2", "e_phase_b4", "f_phase_b6"]
    for name in panels + ["index"]:
        html = (out_dir / f"{name}.html").read_text(encoding="utf-8")
        assert not re.search(r"<script[^>]*src=[\"']?(https?:)?//", html), name  # offline: no remote script
        assert 'src="plotly.min.js"' in html
        if name != "index":  # every panel draws its title (plotly.js takes a title as {"text": ...} only)
            assert re.search(r'"title":\{"text":"\([a-f]\) ', html), name
    assert (out_dir / "plotly.min.js").stat().st_size > 1_000_000
    index = (out_dir / "index.html").read_text(encoding="utf-8")
    assert all(f"{p}.html" in index for p in panels) and index.count('class="panel"') == 6
    assert "states 1-3" in (out_dir / "d_phase_b2.html").read_text(encoding="utf-8")  # Boeing: 3 of 4 drawn
    data = _strict_json((out_dir / "data.json").read_text())
    assert [r["bits"] for r in data["sweep"]["results"]] == [2, 3]
    pp = data["phase_portraits"]
    assert sorted(pp["by_bits"]) == ["2", "4", "6"]
    states = pp["by_bits"]["4"]["states"]
    assert len(states) == 3 and len(states[0]) == 51 and len(states[0][0]) == 4
    assert len(pp["true_model_states"]) == 51
    assert "index.html" in out


MALFORMED = "A = [[0.9, 0.1]\nB = \n"


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["sweep", "--bits", "5:2"], "bits"),
        (["sweep", "--bits", "abc"], "bits must look like"),
        (["sweep", "--bits", "0"], "bits must be between 1 and 32"),
        (["sweep", "--bits", "40"], "bits must be between 1 and 32"),
        (["sweep", "--system", "no-such-system"], "unknown system"),
        (["sweep", "--system", "{tmp}/missing.toml"], "does not exist"),
        (["sweep", "--system", "{tmp}/bad.toml"], "cannot parse"),
        (["sweep", "--range", "diagonal"], "invalid choice"),
        (["sweep", "--realizations", "-3"], "--realizations"),
        (["sweep", "--realizations", "many"], "must be an integer"),
        (["sweep", "--trajectories", "0"], "--trajectories"),
        (["sweep", "--seed", "-1"], "--seed"),
        (["sweep", "--horizon", "500"], "horizon"),
        (["sweep", "--theta", "1.5"], "theta"),
        (["sweep", "--u-max", "1,2,3"], "--u-max"),
        (["sweep", "--no-such-option"], "unrecognized arguments"),
        (["reproduce"], "--out"),
        ([], "give a command"),
    ],
)
def test_bad_inputs_one_line_exit_2(capsys, tmp_path, argv, needle):
    (tmp_path / "bad.toml").write_text(MALFORMED)
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    code, out, err = _run(capsys, *argv)
    assert code == 2
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("qsid: error: ") and needle in lines[0]
    assert "Traceback" not in err and "usage:" not in err


def test_toml_custom_system(capsys, tmp_path):
    f = tmp_path / "plant.toml"
    f.write_text("A = [[0.9, 0.1], [0.0, 0.8]]\nB = [[0.0], [1.0]]\nx0 = [1.0, -1.0]\nQ = [1.0, 2.0]\nR = [[0.5]]\n")
    code, out, err = _run(capsys, "sweep", "--system", str(f), *TINY, "--json", "-q")
    d = _strict_json(out)
    assert code == 0 and err == ""
    assert d["system"] == "plant" and len(d["results"][0]["eps_x"]) == 2 and len(d["results"][0]["eps_u"]) == 1
    assert d["results"][0]["mpc_cost"]["failed"] == 0


def test_json_custom_system(capsys, tmp_path):
    f = tmp_path / "plant.json"
    f.write_text(json.dumps({"A": [[0.5]], "B": [[1.0]]}))
    code, out, _ = _run(capsys, "sweep", "--system", str(f), *TINY, "--no-mpc", "--json", "-q")
    assert code == 0 and _strict_json(out)["system"] == "plant"


def test_uncontrollable_system_warns_once_and_runs(capsys, tmp_path):
    f = tmp_path / "unc.toml"
    f.write_text("A = [[0.9, 0.0], [0.0, 0.8]]\nB = [[1.0], [0.0]]\n")
    code, out, err = _run(capsys, "sweep", "--system", str(f), *TINY, "--json", "-q")
    assert code == 0
    assert [ln for ln in err.splitlines()] == [ln for ln in err.splitlines() if ln.startswith("qsid: warning: ")]
    assert len(err.splitlines()) == 1 and "not controllable" in err
    assert len(_strict_json(out)["results"]) == 3


def test_subprocess_exit_codes(tmp_path):
    bad = subprocess.run(
        [sys.executable, "-m", "app.cli", "sweep", "--bits", "5:2"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert bad.returncode == 2 and bad.stdout == ""
    assert bad.stderr.count("\n") == 1 and bad.stderr.startswith("qsid: error: ")
    good = subprocess.run(
        [sys.executable, "-m", "app.cli", "sweep", *TINY, "--no-mpc", "--json"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert good.returncode == 0, good.stderr
    assert _strict_json(good.stdout)["config"]["realizations"] == 3
    assert "Traceback" not in good.stderr and "quantize + identify" in good.stderr


def test_defaults_and_choices_are_the_engines():
    """One source of truth: the parser's defaults and choices are read from the engine."""
    from app.cli import build_parser
    from qsid_core import MPCConfig, SweepConfig, parse_bits
    from qsid_core.identification.identify import ESTIMATORS
    from qsid_core.quantization.quantize import DITHERS, QuantizerSpec

    a = build_parser().parse_args(["sweep"])
    eng, mpc, quant = SweepConfig(), MPCConfig(), QuantizerSpec()
    assert parse_bits(a.bits) == eng.bits
    assert (a.realizations, a.trajectories, a.steps, a.theta) == (
        eng.realizations,
        eng.trajectories,
        eng.steps,
        eng.theta,
    )
    assert (a.horizon, a.mpc_steps, a.u_max) == (mpc.horizon, mpc.steps, mpc.u_max)
    assert (a.dither, a.range_mode, a.estimator) == (quant.dither, quant.range_mode, eng.estimator)
    for d in DITHERS:
        assert build_parser().parse_args(["sweep", "--dither", d]).dither == d
    for e in ESTIMATORS:
        assert build_parser().parse_args(["sweep", "--estimator", e]).estimator == e


def test_json_is_strict_for_numpy_nonfinite_and_enums():
    import enum

    import numpy as np

    from app.cli.output import dumps

    class Kind(enum.Enum):
        DIVERGED = "diverged"

    text = dumps(
        {"a": np.array([1.0, np.nan]), "b": np.float64(np.inf), "k": [Kind.DIVERGED], Kind.DIVERGED: 2}, indent=None
    )
    assert text == '{"a": [1.0, null], "b": null, "k": ["diverged"], "diverged": 2}'
