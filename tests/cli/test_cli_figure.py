"""``qsid sweep --figure`` and ``qsid reproduce --figure``; reproduce for 1- and 2-state systems (time axis)."""

import json
import re
from pathlib import Path

import pytest

from app.cli import main

TINY = ["--trajectories", "10", "--steps", "100", "--realizations", "2", "--bits", "2:4"]
CHROMIUM = "/usr/bin/chromium"


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def _need_browser():
    if not Path(CHROMIUM).exists():
        pytest.skip(f"{CHROMIUM} is missing (apt-get install chromium)")
    pytest.importorskip("playwright.sync_api")


@pytest.mark.parametrize(
    "extra, needle",
    [
        (["--figure", "f.jpg"], "argument --figure: 'DIR/f.jpg' has the suffix '.jpg'; give .png, .svg, .pdf or .html"),
        (["--figure", "f.png", "--figure-view", "cost", "--no-mpc"], "'cost' needs the closed loops; drop --no-mpc"),
        (["--figure", "same.html", "--out", "same.html"], "arguments --out and --figure name the same file"),
        (["--figure-view", "nyquist"], "invalid choice: 'nyquist'"),
    ],
)
def test_bad_figure_flags_are_one_line_errors_before_the_run(capsys, tmp_path, extra, needle):
    extra = [str(tmp_path / e) if e.endswith((".jpg", ".png", ".html")) else e for e in extra]
    code, out, err = _run(capsys, "sweep", *TINY, *extra)
    assert code == 2 and out == ""
    assert needle.replace("DIR", str(tmp_path)) in err and len(err.strip().splitlines()) == 1
    assert not list(tmp_path.iterdir())  # nothing written


def test_sweep_figure_html_holds_the_result(capsys, tmp_path):
    f = tmp_path / "err.html"
    code, out, err = _run(capsys, "sweep", *TINY, "--no-mpc", "--json", "--figure", str(f))
    assert code == 0, err
    res = json.loads(out)
    html = f.read_text()
    assert not re.search(r"<script[^>]*src=[\"']?(https?:)?//", html)  # plotly.js inline: offline
    assert "Theorem 1" in html and "word length b [bits]" in html
    assert f"{res['results'][0]['err_A']['mean']:.6g}"[:6] in html  # the numbers drawn are the run's


def test_sweep_figure_without_chromium_falls_back_to_html_and_says_why(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("QSID_CHROMIUM", str(tmp_path / "no-chromium"))
    code, out, err = _run(capsys, "sweep", *TINY, "--no-mpc", "--figure", str(tmp_path / "f.png"))
    assert code == 0, err
    assert (tmp_path / "f.html").exists() and not (tmp_path / "f.png").exists()
    (note,) = [ln for ln in err.splitlines() if "note: --figure" in ln]
    assert "no Chromium at" in note and "instead of f.png" in note


@pytest.mark.browser
def test_sweep_figure_png_of_the_stabilized_view(capsys, tmp_path):
    _need_browser()
    f = tmp_path / "stab.png"
    code, out, err = _run(
        capsys, "sweep", *TINY, "--mpc-steps", "10", "--figure", str(f), "--figure-view", "stabilized"
    )
    assert code == 0, err
    data = f.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    assert "figure (stabilized) written to" in err


def _small_system(tmp_path, n: int) -> Path:
    f = tmp_path / f"s{n}.toml"
    if n == 1:
        f.write_text('name = "one"\nA = [[0.9]]\nB = [[0.5]]\nx0 = [1.0]\n')
    else:
        f.write_text('name = "two"\nA = [[0.9, 0.1], [0.0, 0.8]]\nB = [[0.0], [1.0]]\nx0 = [1.0, 1.0]\n')
    return f


@pytest.mark.parametrize("n", [1, 2])
def test_reproduce_draws_one_and_two_state_systems_with_a_time_axis(capsys, tmp_path, n):
    out_dir = tmp_path / "fig"
    code, out, err = _run(
        capsys, "reproduce", "--system", str(_small_system(tmp_path, n)), "--out", str(out_dir), *TINY
    )
    assert code == 0, err
    data = json.loads((out_dir / "data.json").read_text())
    pp = data["phase_portraits"]
    assert pp["drawn_states"] == list(range(n)) and pp["time_axes"] == list(range(n, 3))
    html = (out_dir / "d_phase_b2.html").read_text()
    args = html.split("Plotly.newPlot(", 1)[1].split(",", 1)[1].lstrip()  # after the div's id: data, layout
    traces, end = json.JSONDecoder().raw_decode(args)
    layout = json.JSONDecoder().raw_decode(args[end:].lstrip(", \n"))[0]
    types = {t["type"] for t in traces}
    steps = len(pp["true_model_states"])
    if n == 2:  # 3-D: x1, x2 and the step k on z
        assert types == {"scatter3d"} and "time (step k) on the third axis" in html
        assert layout["scene"]["zaxis"]["title"]["text"] == "step k (time)"
    else:  # 2-D: x1 against the step k
        assert types == {"scatter"} and "the state against time (step k)" in html
        assert layout["xaxis"]["title"]["text"] == "step k (time)"
    assert steps == 51 and len(pp["by_bits"]["2"]["states"][0][0]) == n


def test_reproduce_figure_formats_are_checked_before_the_run(capsys, tmp_path):
    code, out, err = _run(capsys, "reproduce", *TINY, "--out", str(tmp_path / "o"), "--figure", "png,gif")
    assert code == 2 and "give png, svg and/or pdf" in err and not (tmp_path / "o").exists()


@pytest.mark.browser
def test_reproduce_figure_writes_every_panel_as_png(capsys, tmp_path):
    _need_browser()
    out_dir = tmp_path / "fig"
    code, out, err = _run(
        capsys,
        "reproduce",
        "--system",
        str(_small_system(tmp_path, 2)),
        "--out",
        str(out_dir),
        *TINY,
        "--figure",
        "png",
    )
    assert code == 0, err
    pngs = sorted(p.name for p in out_dir.glob("*.png"))
    assert pngs == [
        "a_error_A.png",
        "b_error_B.png",
        "c_mpc_cost.png",
        "d_phase_b2.png",
        "e_phase_b4.png",
        "f_phase_b6.png",
    ]
    assert all((out_dir / p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)


def test_the_figure_views_the_parser_offers_are_the_plotting_views():
    from app.cli.figure_out import FIGURE_VIEWS
    from app.figures.results import VIEWS

    assert FIGURE_VIEWS == VIEWS
