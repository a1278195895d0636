"""``qsid reproduce`` for a nonlinear plant: the figures (error vs b with LS and BCLS, prediction, outcomes,
eigenvalues, phase portraits of the flow and the loops) and data.json, whose rows equal ``qsid sweep``'s."""

from __future__ import annotations

import json

import pytest

from app.cli.main import main


@pytest.mark.slow  # a small nonlinear sweep for both estimators, with loops
def test_reproduce_writes_the_nonlinear_figures_and_the_sweeps_rows(tmp_path, capsys):
    out = tmp_path / "vdp"
    small = ["--trajectories", "30", "--steps", "50", "--realizations", "2", "--mpc-steps", "30", "--horizon", "8"]
    argv = ["reproduce", "--system", "van-der-pol", "--lifting", "poly:2", *small, "--bits", "3:4", "-q"]
    assert main([*argv, "--out", str(out)]) == 0
    names = {p.name for p in out.iterdir()}
    want = {"a_error", "b_prediction", "c_outcomes", "d_eigenvalues", "e_phase_b2", "f_phase_b4", "g_phase_b6"}
    assert {f"{n}.html" for n in want} | {"index.html", "data.json", "plotly.min.js"} <= names
    page = (out / "a_error.html").read_text()
    assert "LS: quantized EDMD" in page and "BCLS: quantized EDMD" in page and "LS large-data limit" in page
    assert "free flow (u = 0)" in (out / "e_phase_b2.html").read_text()
    for name in want:  # every panel draws its title (plotly.js takes a title as {"text": ...} only)
        assert '"title":{"text":"(' in (out / f"{name}.html").read_text(), name
    index = (out / "index.html").read_text()  # every panel drawn inline, as the linear page does
    assert '<script src="plotly.min.js"></script>' in index and "Plotly.newPlot" in index
    for name in want:
        assert f'id="panel-{name}"' in index and f'<a href="{name}.html">' in index, name
    data = json.loads((out / "data.json").read_text())
    assert data["bits"] == [2, 3, 4, 6] and "do not apply" in data["certificates"]
    capsys.readouterr()
    assert main(["sweep", "--system", "van-der-pol", "--lifting", "poly:2", *small, "--bits", "3", "--json", "-q"]) == 0
    sweep = json.loads(capsys.readouterr().out)["results"][0]
    mine = next(r for r in data["results"]["LS"] if r["bits"] == 3)
    assert mine["err_G"] == sweep["err_G"] and mine["closed_loop_outcomes"] == sweep["closed_loop_outcomes"]


def test_reproduce_refuses_a_bad_dictionary_in_one_line(tmp_path, capsys):
    code = main(["reproduce", "--system", "van-der-pol", "--lifting", "poly:0", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert code != 0 and "degree must be 1..8" in err and "Traceback" not in err
