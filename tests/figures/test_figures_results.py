"""Figures straight from SweepResults (several on one figure, theory per series) and the offline static export."""

import json
import os
import struct
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from app.figures.export import ExportError, save_figure, save_figures
from app.figures.results import FigureError, plot_results, result_series
from qsid_core import MPCConfig, QuantizerSpec, SweepConfig, load_result, run_sweep

SMALL = dict(system="boeing747", bits=(2, 3, 4, 5), trajectories=20, steps=300, realizations=2)
CHROMIUM = "/usr/bin/chromium"


@pytest.fixture(scope="module")
def results():
    """LS and BCLS with subtractive dither, and LS with TPDF (another Theorem 1 line), identification only."""
    return [
        run_sweep(SweepConfig(estimator="ls", mpc=None, **SMALL)),
        run_sweep(SweepConfig(estimator="bcls", mpc=None, **SMALL)),
        run_sweep(SweepConfig(estimator="ls", quantizer=QuantizerSpec(dither="tpdf"), mpc=None, **SMALL)),
    ]


@pytest.fixture(scope="module")
def with_mpc():
    mpc = MPCConfig(steps=15, horizon=5)
    return [run_sweep(SweepConfig(estimator=e, mpc=mpc, **SMALL)) for e in ("ls", "bcls")]


def _theory_traces(fig):
    return [t for t in fig.data if t.name and t.name.startswith("Theorem 1")]


def test_error_view_draws_every_result_and_a_theory_line_per_distinct_prediction(results):
    fig = plot_results(*results)
    names = {t.name for t in fig.data if t.showlegend is not False and t.name}
    labels = list(result_series(*results)[0])
    assert labels == ["LS, dither subtractive", "BCLS, dither subtractive", "LS, dither tpdf"]
    assert set(labels) <= names
    theory = {t.name.replace(" (hypotheses fail)", "") for t in _theory_traces(fig)}
    # LS and BCLS share the data and so Theorem 1's prediction (drawn once); TPDF's eps^2/4 gives its own line
    assert theory == {"Theorem 1 · LS, dither subtractive", "Theorem 1 · LS, dither tpdf"}
    tp = [t for t in _theory_traces(fig) if t.name == "Theorem 1 · LS, dither tpdf" and t.xaxis in (None, "x")][0]
    rows = results[2].to_dict()["results"]
    drawn = [y for y in tp.y if y is not None and np.isfinite(y)]
    assert drawn and all(any(abs(y - r["err_A_theory"]) < 1e-12 for r in rows) for y in drawn)


def test_one_result_keeps_the_dashboards_look_and_labels_can_be_given(results):
    fig = plot_results(results[0])
    assert {t.name for t in _theory_traces(fig)} <= {"Theorem 1", "Theorem 1 (hypotheses fail)"}
    assert "LS" in {t.name for t in fig.data}
    fig = plot_results(*results[:2], labels=["plain", "compensated"])
    assert {"plain", "compensated"} <= {t.name for t in fig.data}


def test_loaded_results_dicts_and_paths_plot_like_fresh_ones(results, tmp_path):
    p = tmp_path / "r.json"
    p.write_text(json.dumps(results[0].to_dict()))
    fresh = plot_results(results[0]).to_dict()["data"]
    for other in (load_result(p), results[0].to_dict(), p, str(p)):
        assert plot_results(other).to_dict()["data"] == fresh


def test_bound_view_has_a_delta_line_per_distinct_result(results):
    fig = plot_results(*results, view="bound")
    deltas = [t.name for t in fig.data if t.name and t.name.startswith("letter's δ")]
    assert deltas == [
        "letter's δ(ε) (Theorem 1 errors) · LS, dither subtractive",
        "letter's δ(ε) (Theorem 1 errors) · LS, dither tpdf",
    ]


def test_cost_and_stabilized_views_from_mpc_results(with_mpc):
    cost = plot_results(*with_mpc, view="cost")
    assert {"LS model", "BCLS model"} <= {t.name for t in cost.data}
    assert any("true model" in (a.text or "") for a in cost.layout.annotations)
    stab = plot_results(*with_mpc, view="stabilized")
    assert {"LS stabilized", "BCLS stabilized"} <= {t.name for t in stab.data}
    ls = [t for t in stab.data if t.name == "LS stabilized"][0]
    oc = [r["closed_loop_outcomes"] for r in with_mpc[0].to_dict()["results"]]
    assert list(ls.y) == [100 * o["converged"] / sum(o.values()) for o in oc]
    # the title is the engine's own answer (qsid bits), the small-gain certificate recomputed from the config
    from qsid_core.studies.bits import bits_needed

    engine = bits_needed(with_mpc[0].config)
    ls_title = stab.layout.title.text.split("<br>BCLS")[0]
    assert ls_title.replace("<br>", "").replace(" ", "") == f"LS: {engine.sentence}".replace(" ", "")
    assert "certificate holds from b =" in engine.sentence  # recomputed, not "not computed" for want of it


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        (dict(view="nyquist"), "view: 'nyquist' is not one of error, cost, stabilized, bound"),
        (dict(labels=["one"]), "labels: 1 labels for 3 results"),
        (dict(labels=["a", "a", "b"]), "labels: every label must be different"),
        (dict(view="cost"), "has no MPC cost"),
        (dict(view="stabilized"), "has no closed loops"),
    ],
)
def test_bad_arguments_are_one_clear_error(results, kwargs, needle):
    with pytest.raises(FigureError, match=needle.replace("(", r"\(").replace(")", r"\)")):
        plot_results(*results, **kwargs)


def test_no_results_or_a_wrong_type_is_refused():
    with pytest.raises(FigureError, match="at least one"):
        plot_results()
    with pytest.raises(FigureError, match=r"results\[0\]: expected a SweepResult"):
        plot_results([1, 2])


# ----- static export ------------------------------------------------------------------------------------------
def test_bad_suffix_directory_or_folder_is_one_clear_error(results, tmp_path):
    fig = plot_results(results[0])
    for path, needle in (
        (tmp_path / "f.jpg", "has the suffix '.jpg'; give .png, .svg, .pdf or .html"),
        (tmp_path / "f", "has no suffix"),
        (tmp_path / "nope" / "f.png", "does not exist"),
    ):
        with pytest.raises(ExportError, match=needle.replace(".", r"\.")):
            save_figure(fig, path)
    d = tmp_path / "d.png"
    d.mkdir()
    with pytest.raises(ExportError, match="is a directory"):
        save_figure(fig, d)
    assert isinstance(ExportError("x"), ValueError)


def test_without_chromium_it_writes_offline_html_and_says_why(results, tmp_path):
    saved = save_figure(plot_results(results[0]), tmp_path / "f.png", browser=str(tmp_path / "no-chromium"))
    assert saved.format == "html" and saved.path == tmp_path / "f.html" and not (tmp_path / "f.png").exists()
    assert "no Chromium at" in saved.note and "f.html instead of f.png" in saved.note and "\n" not in saved.note
    text = saved.path.read_text()
    assert "<script src=" not in text.split("Plotly.newPlot")[0].lower()  # plotly.js inline: offline


def _png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


@pytest.mark.browser
def test_png_svg_pdf_offline_in_chromium_and_the_browser_ends(results, tmp_path):
    if not Path(CHROMIUM).exists():
        pytest.skip(f"{CHROMIUM} is missing (apt-get install chromium)")
    pytest.importorskip("playwright.sync_api")
    from support import descendants, gone_within

    fig = plot_results(*results)
    before = set(descendants(os.getpid()))
    png = save_figure(fig, tmp_path / "f.png", width=800, height=400, scale=2)
    # the other two in one Chromium (save_figures, as the CLI draws several figures)
    svg, pdf = save_figures([(fig, tmp_path / "f.svg"), (fig, tmp_path / "f.pdf")], width=800, height=400)
    assert [s.note for s in (png, svg, pdf)] == ["", "", ""]
    data = png.path.read_bytes()
    assert _png_size(data) == (1600, 800) and len(data) > 20_000  # drawn, not a blank page
    root = ET.parse(svg.path).getroot()
    assert root.tag.endswith("svg") and root.get("viewBox") == "0 0 800 400"
    assert "LS, dither tpdf" in svg.path.read_text()  # the legend is in it
    raw = pdf.path.read_bytes()
    assert raw.startswith(b"%PDF") and raw.rstrip().endswith(b"%%EOF") and len(raw) > 5_000
    left = set(descendants(os.getpid())) - before
    assert gone_within(sorted(left), 60) == []  # Chromium and the playwright driver ended


def test_a_browser_that_does_not_start_falls_back_to_html_with_its_first_line(results, tmp_path):
    pytest.importorskip("playwright.sync_api")
    saved = save_figure(plot_results(results[0]), tmp_path / "f.svg", browser="/bin/false")
    assert saved.format == "html" and saved.path.exists() and not (tmp_path / "f.svg").exists()
    assert saved.note.startswith("Chromium at /bin/false did not start (") and "\n" not in saved.note
