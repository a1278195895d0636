"""``qsid datalength``: one JSON row per length (LS/BCLS mean and std, Theorem 1's floor, chosen runs x steps),
a table on stdout, progress on stderr, one-line errors."""

import json

import pytest

from app.cli import main

ARGS = ["datalength", "--system", "boeing747", "--bits", "4", "--samples", "1000,20000", "--realizations", "3"]


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_json_rows_per_length(capsys):
    code, out, err = _run(capsys, *ARGS, "--json")
    assert code == 0, err
    d = json.loads(out)
    assert d["system"] == "boeing747" and d["bits"] == 4 and d["config"]["guard"] is True
    assert [r["samples"] for r in d["rows"]] == [1000, 20000]
    for r in d["rows"]:
        assert r["trajectories"] * r["steps"] == r["samples"]
        for est in ("ls", "bcls"):
            for k in ("err_A", "err_B"):
                assert set(r[est][k]) >= {"mean", "std"} and r[est][k]["mean"] > 0
        assert r["err_A_theory"] > 0 and r["err_B_theory"] > 0
    # finite-data error falls with T; LS ends near Theorem 1's floor, BCLS below it
    ls = [r["ls"]["err_A"]["mean"] for r in d["rows"]]
    bc = [r["bcls"]["err_A"]["mean"] for r in d["rows"]]
    assert bc[1] < bc[0] and bc[1] < d["rows"][1]["err_A_theory"]
    assert ls[1] == pytest.approx(d["rows"][1]["err_A_theory"], rel=0.3)
    assert "runs x steps per length: 1000: 10x100, 20000: 20x1000" in err and "T = 20000" in err


def test_table_on_stdout(capsys, tmp_path):
    target = tmp_path / "dl.json"
    code, out, err = _run(capsys, *ARGS, "--no-guard", "--dither", "none", "--out", str(target), "-q")
    assert code == 0 and err == ""
    lines = out.splitlines()
    assert "b = 4" in lines[0] and "no guard" in lines[0] and "dither none" in lines[0]
    assert lines[1].split()[:4] == ["T", "runs", "x", "steps"]
    assert [ln.split()[0] for ln in lines[3:5]] == ["1000", "20000"] and "10 x 100" in lines[3]
    assert json.loads(target.read_text())["config"]["dither"] == "none"


@pytest.mark.parametrize(
    "extra, needle",
    [
        (["--samples", "abc"], "sample counts"),
        (["--samples", "1.5"], "whole numbers"),
        (["--samples", "5"], "samples"),
        (["--bits", "0"], "--bits"),
        (["--range", "fixed"], "--limits"),
        (["--system", "nope"], "unknown system"),
    ],
)
def test_bad_input_one_line(capsys, extra, needle):
    code, out, err = _run(capsys, *ARGS, *extra)
    assert code == 2 and out == ""
    assert len(err.splitlines()) == 1 and err.startswith("qsid: error: ") and needle in err, err


def test_the_settings_tables_options_and_seed(capsys):
    """The study's options are the settings table's (its ``datalength`` column): the what-ifs reach the study and
    its record, ``--seed`` gives both seeds unless one is typed."""
    code, out, err = _run(
        capsys,
        *ARGS,
        "--state-amplitude",
        "2",
        "--noise",
        "0.01",
        "--noise-known",
        "--input-bits",
        "exact",
        "--seed",
        "5",
        "--dither-seed",
        "8",
        "--json",
        "-q",
    )
    assert code == 0, err
    c = json.loads(out)["config"]
    assert (c["state_amplitude"], c["noise"], c["noise_known"], c["input_bits"]) == (2.0, [0.01], True, "exact")
    assert (c["data_seed"], c["dither_seed"]) == (5, 8)
    code, out, _ = _run(capsys, *ARGS, "--state-bits", "b,exact,b,b", "-q")  # boeing747: 4 states, 2 inputs
    assert code == 0 and "state bits b,exact,b,b" in out.splitlines()[0]


@pytest.mark.parametrize(
    "extra, needle",
    [
        (["--input-bits", "4,4,4"], "input"),
        (["--noise", "0.1,0.1"], "noise"),
        (["--state-amplitude", "0"], "amplitude"),
    ],
)
def test_a_what_if_that_does_not_fit_is_one_line(capsys, extra, needle):
    code, out, err = _run(capsys, *ARGS, *extra)
    assert code == 2 and out == ""
    assert len(err.splitlines()) == 1 and err.startswith("qsid: error: ") and needle in err, err
