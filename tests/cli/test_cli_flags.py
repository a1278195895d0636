"""``qsid`` flags for every dashboard setting: guard, fixed limits, input amplitude, x0/x_ref/x_max/Q/R, seeds,
inline systems; ``reproduce`` keeps the letter's settings and says so; the table carries the assumption flags."""

import json

import numpy as np
import pytest

from app.cli import build_parser, main
from app.cli.runner import config, system_from_args
from qsid_core import QuantizerSpec, SweepConfig
from qsid_core.quantization.quantize import LETTER_QUANTIZER

TINY = ["--trajectories", "5", "--steps", "100", "--realizations", "3", "--bits", "2:4"]


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def _cfg(*argv, mpc=True):
    args = build_parser().parse_args(["sweep", *argv])
    return config(args, system_from_args(args), mpc)


def test_guard_default_is_the_engines_and_can_be_turned_off():
    assert _cfg().quantizer.guard is QuantizerSpec().guard is True
    assert _cfg("--no-guard").quantizer.guard is False
    assert _cfg("--guard").quantizer.guard is True


def test_fixed_range_one_pair_and_per_channel():
    q = _cfg("--range", "fixed", "--limits=-20,20").quantizer
    assert q.range_mode == "fixed" and q.fixed_range == ((-20.0, 20.0),)
    pairs = "-1,1;-2,2;-3,3;-0.5,0.5;-4,4"  # dc-motor: 3 states then 2 inputs
    q = _cfg("--range", "fixed", f"--limits={pairs}").quantizer
    assert q.fixed_range == ((-1.0, 1.0), (-2.0, 2.0), (-3.0, 3.0), (-0.5, 0.5), (-4.0, 4.0))


def test_fixed_range_reaches_the_quantizer(capsys):
    code, out, err = _run(
        capsys, "sweep", *TINY, "--range", "fixed", "--limits=-20,20", "--no-guard", "--no-mpc", "--json", "-q"
    )
    assert code == 0, err
    d = json.loads(out)
    assert d["config"]["fixed_range"] == [[-20.0, 20.0]] and d["config"]["guard"] is False
    for r in d["results"]:  # eps = 40 / 2^b on every channel
        assert r["eps_x"] + r["eps_u"] == pytest.approx([40.0 / 2 ** r["bits"]] * 5)


def test_input_amplitude_x0_xref_xmax_q_r_seeds():
    c = _cfg(
        "--input-amplitude",
        "0.25",
        "--x0=-1,0.5,2",
        "--x-ref",
        "0.1",
        "--x-max",
        "3,4,5",
        "--Q",
        "1,0,2",
        "--R",
        "0.5",
        "--data-seed",
        "7",
        "--dither-seed",
        "9",
    )
    assert c.input_amplitude == 0.25 and (c.data_seed, c.dither_seed) == (7, 9)
    m = c.mpc
    assert m.x0 == (-1.0, 0.5, 2.0) and m.x_ref == (0.1,) and m.x_max == (3.0, 4.0, 5.0)
    assert m.Q == (1.0, 0.0, 2.0) and m.R == (0.5,)
    r = m.resolve(c.system)
    assert np.allclose(r.x_ref, [0.1] * 3) and np.allclose(np.diag(r.R), [0.5, 0.5])
    # --seed sets both, the separate seeds win over it
    c = _cfg("--seed", "3", "--dither-seed", "5")
    assert (c.data_seed, c.dither_seed) == (3, 5)


def test_mpc_settings_in_the_json(capsys):
    code, out, err = _run(
        capsys,
        "sweep",
        *TINY,
        "--x0=0.5,0,0",
        "--x-ref",
        "0.1",
        "--x-max",
        "5",
        "--Q",
        "2",
        "--R",
        "0.5",
        "--input-amplitude",
        "0.5",
        "--json",
        "-q",
    )
    assert code == 0, err
    c = json.loads(out)["config"]
    assert c["input_amplitude"] == 0.5
    assert c["mpc"]["x0"] == [0.5, 0.0, 0.0] and c["mpc"]["x_ref"] == [0.1] * 3 and c["mpc"]["x_max"] == [5.0] * 3
    assert c["mpc"]["Q"] == [2.0] * 3 and c["mpc"]["R"] == [0.5, 0.5]


def test_inline_system_like_the_dashboard(capsys):
    c = _cfg("--A", "0.9 0.1; 0 0.8", "--B", "0; 1")
    assert c.system.name == "custom" and c.system.A.tolist() == [[0.9, 0.1], [0.0, 0.8]]
    code, _, err = _run(capsys, "sweep", "--A", "0.9")
    assert code == 2 and "both --A and --B" in err and len(err.splitlines()) == 1


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["--range", "fixed"], "needs --limits"),
        (["--limits=-1,1"], "only used with --range fixed"),
        (["--range", "fixed", "--limits=-1,1;-2,2"], "1 pair or 5 pairs"),
        (["--range", "fixed", "--limits", "2,1"], "LO < HI"),
        (["--range", "fixed", "--limits", "a,b"], "not a number"),
        (["--range", "fixed", "--limits", "-1,1"], "needs '='"),
        (["--x0", "1,,2"], "--x0"),
        (["--x0", "1,2"], "x0"),
        (["--Q", "nan"], "not finite"),
        (["--R=-1"], "R"),
        (["--x-max", "0"], "x_max"),
        (["--input-amplitude", "0"], "--input-amplitude: must be >= 1e-06"),
        (["--data-seed", "-1"], "--data-seed"),
    ],
)
def test_bad_new_flags_one_line_exit_2(capsys, argv, needle):
    code, out, err = _run(capsys, "sweep", *TINY, *argv, "-q")
    assert code == 2 and out == ""
    assert len(err.splitlines()) == 1 and err.startswith("qsid: error: ") and needle in err, err


def test_reproduce_defaults_are_the_letters_and_it_says_so(capsys, tmp_path):
    args = build_parser().parse_args(["reproduce", "--out", str(tmp_path / "x")])
    letter = SweepConfig.letter()
    c = config(args, system_from_args(args), True)
    assert c.quantizer == LETTER_QUANTIZER and c.quantizer.guard is False
    assert (c.bits, c.realizations, c.trajectories, c.steps, c.estimator, c.input_amplitude) == (
        letter.bits,
        letter.realizations,
        letter.trajectories,
        letter.steps,
        letter.estimator,
        letter.input_amplitude,
    )
    code, out, err = _run(
        capsys,
        "reproduce",
        "--out",
        str(tmp_path / "fig"),
        "--system",
        "boeing747",
        *TINY[:-2],
        "--bits",
        "2:3",
        "--guard",
    )
    assert code == 0, err
    line = next(ln for ln in err.splitlines() if "the letter's settings" in ln)
    assert "no guard band" in line and "subtractive dither" in line and "per-channel range" in line
    assert "changed by your options:" in line and "guard on" in line and "trajectories 5" in line
    assert json.loads((tmp_path / "fig" / "data.json").read_text())["sweep"]["config"]["guard"] is True


def test_table_carries_the_assumption_flags(capsys):
    # dc-motor: the angle is an integrator, so Theorem 1's stationarity hypothesis fails at every b
    code, out, _ = _run(capsys, "sweep", *TINY, "--no-mpc", "-q")
    assert code == 0
    lines = out.splitlines()
    assert "Thm1/BCLS hold" in lines[1]
    assert all(ln.split()[-1] in ("no/yes", "no/no") for ln in lines[3:6])
    assert any(ln.startswith("assumptions: Theorem 1's line does not apply at b = 2..4") for ln in lines)
    assert any("Psi Psi^T/T converges" in ln and "b = 2..4" in ln for ln in lines)
    code, out, _ = _run(capsys, "sweep", *TINY, "--no-mpc", "--json", "-q")
    for r in json.loads(out)["results"]:
        a = r["assumptions"]
        assert a["stationary"] is False and a["theorem1_holds"] is False and isinstance(a["no_overload"], bool)


def test_threads_give_the_same_numbers_as_one_thread_and_bad_counts_are_usage_errors(capsys):
    small = ("sweep", "--trajectories", "20", "--steps", "100", "--realizations", "5", "--bits", "2:8", "--json", "-q")
    one = json.loads(_run(capsys, *small, "--threads", "1")[1])
    two = json.loads(_run(capsys, *small, "--threads", "2")[1])
    assert one["results"] == two["results"] and one["results"]
    code, _, err = _run(capsys, *small, "--threads", "0")
    assert code == 2 and "--threads" in err and "Traceback" not in err
