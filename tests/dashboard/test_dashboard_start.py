"""The guided start: ``qsid-dashboard`` opens on it, it cites the letter, every claim of its text holds on the
numbers the dashboard computes at the default settings; the glossary it points to; the default sweep's plain
sentence on why Theorem 1 does not apply to the default plant."""

from __future__ import annotations

import re

import numpy as np
import pytest
from support import ROOT, SMALL, Tab

from app.cli import main as cli_main
from app.dashboard.options import read_options
from app.figures.error_vs_bits import error_figure
from app.frames.frame import full_row
from app.lessons.drift import lesson_drift, lesson_markdown
from app.lessons.start import LETTER_URL, START
from app.lessons.table import LESSONS, get_lesson, lesson_values
from app.settings.config import sweep_config
from app.settings.values import Values, resolve_system
from qsid_core import Experiment
from qsid_core.studies import fit_slope

ARXIV = "2503.19102"
#: What the glossary must define (issue 38), as its terms are written in docs/glossary.rst.
TERMS = (
    "ε",
    "ρ",
    "δ(ε)",
    "BCLS",
    "EDMD",
    "Ψ Ψᵀ",
    "b_observed",
    "b_robust",
    "b_letter",
    "small-gain certificate",
    "subtractive dither",
    "Theorem 1",
)


def test_the_start_is_the_first_lesson_cites_the_letter_and_points_on():
    les = get_lesson(START)
    assert LESSONS[0] is les and les.title == "Start here" and les.plot == "error"
    assert ARXIV in les.text and LETTER_URL == f"https://arxiv.org/abs/{ARXIV}" and LETTER_URL in les.text
    assert "Ataei, Maity, Goswami" in les.text and "Quantized Data" in les.text
    assert "**fig1**" in les.text and "docs/glossary.rst" in les.text  # the next lesson, the words
    for what in ("3-D", "plots", "Summary", "Move b first"):  # the three panels, the slider to move first
        assert what in les.text, what
    assert lesson_markdown(START).startswith("**Start here.**")


def test_qsid_dashboard_opens_on_the_start_unless_told_otherwise(tmp_path):
    assert read_options([])[0].lesson == START
    assert read_options(["--scale", "paper"])[0].lesson == START
    assert read_options(["--lesson", "fig2"])[0].lesson == "fig2"
    assert read_options(["--system", "boeing747"])[0].lesson is None  # the text is about the default plant
    f = tmp_path / "s.json"
    from app.settings.files import settings_json

    f.write_text(settings_json(Values(system="dc-motor", bits=6)), encoding="utf-8")
    assert read_options(["--settings", str(f)])[0].lesson is None  # a settings file is opened as it was saved


def test_the_start_text_is_marked_once_a_setting_its_claims_rest_on_changes():
    v = lesson_values(START)
    assert v == Values().replace(lesson=START)  # the start is the default panel itself
    assert lesson_drift(START, v.replace(bits=9)) == ()  # moving b is the point
    assert lesson_drift(START, v.replace(trajectories=200)) == ("trajectories",)  # its slopes are the default data's
    assert "system" in lesson_drift(START, v.replace(system="boeing747"))  # the text is about the motor


@pytest.mark.slow
def test_every_claim_of_the_start_text_holds_at_the_default_settings():
    v = lesson_values(START)
    ex = Experiment(sweep_config(v, resolve_system(v).system))
    bits = range(1, 17)
    text = get_lesson(START).text
    assert "the errors fall about 0.3 decades per bit" in text
    for est in ("ls", "bcls"):
        errs = [np.mean(ex.identification(b, est).err_A) for b in bits]
        assert -0.36 < fit_slope(list(bits), errs) < -0.26, est
    assert "the coloured loops close in on the black one" in text
    xt = ex.true_model_loop().states[0]
    for est in ("ls", "bcls"):
        far = [
            float(np.nanmean(np.max(np.linalg.norm(ex.closed_loops(b, est).states - xt, axis=-1), axis=1)))
            for b in (2, 4, 6, 8)
        ]
        assert far == sorted(far, reverse=True) and far[-1] < 0.02 * far[0], (est, far)
    assert "Theorem 1's line is faded because the motor's angle is an integrator" in text
    rows = [full_row(ex, "ls", b, ex.closed_loops(b, "ls")) for b in bits]
    assert all(not r["assumptions"]["stationary"] and not r["assumptions"]["theorem1_holds"] for r in rows)
    fig = error_figure({"LS": rows})
    assert "Theorem 1" not in [t.name for t in fig.data] and "Theorem 1 (hypotheses fail)" in [t.name for t in fig.data]
    assert "the theorem1 lesson shows the theorem hold on the Boeing 747" in text
    th = lesson_values("theorem1")
    assert th.system == "boeing747"
    assert "δ(ε) is a bound only below ρ, here from b = 5 on" in text
    consistent = [r["bits"] for r in rows if r["bound_self_consistent"]]
    assert consistent == list(range(5, 17)), consistent


@pytest.mark.slow
def test_a_new_tab_of_the_default_dashboard_shows_the_start_text():
    from app.dashboard import DashboardApp

    args = read_options(["--port", "0"])[0]
    app = DashboardApp(host="127.0.0.1", port=0, workers=0, lesson=args.lesson)
    try:
        t = Tab(app).wait()
        c = t.controls
        assert c["lesson"].value == START and c.lesson_text.visible and ARXIV in c.lesson_text.content
        assert t.frame.system.name == "dc-motor" and t.error is None
        t.set(**SMALL)  # the text's claims rest on the default data: a smaller data set marks it, naming what moved
        assert "Modified" in c.lesson_text.content and "trajectories" in c.lesson_text.content
        t.set(system="boeing747")
        assert "Modified from the lesson" in c.lesson_text.content
        t.close()
    finally:
        app.stop()


def test_the_glossary_holds_the_terms_and_is_in_the_toctree():
    text = (ROOT / "docs" / "glossary.rst").read_text(encoding="utf-8")
    block = text.split(".. glossary::", 1)[1]
    terms = set(re.findall(r"^   (\S[^\n]*)$", block, flags=re.M))  # a term: indented 3, its text 6
    missing = [t for t in TERMS if t not in terms]
    assert not missing, missing
    assert ARXIV in text and LETTER_URL in text
    index = (ROOT / "docs" / "index.rst").read_text(encoding="utf-8")
    assert re.search(r"^   glossary$", index, flags=re.M)


def test_readme_and_docs_index_cite_the_letter():
    for path in ("README.md", "docs/index.rst"):
        text = (ROOT / path).read_text(encoding="utf-8")
        head = " ".join(text[:1500].split())  # (the citation may be wrapped)
        assert "Ataei, Maity, Goswami" in head and "Model Predictive Control with System Identification from" in head
        assert f"arXiv {ARXIV}" in head and LETTER_URL in head, path


def test_the_panel_hints_point_to_the_glossary():
    from app.dashboard.controls import CONTROLS

    pointing = [c.name for c in CONTROLS if c.hint and "docs/glossary.rst" in c.hint]
    assert {"lesson", "bits", "identification", "rho_auto"} <= set(pointing), pointing


def test_the_default_sweep_says_why_theorem1_does_not_apply_and_where_it_does(capsys):
    tiny = ["--trajectories", "5", "--steps", "100", "--realizations", "3", "--bits", "2:4", "--no-mpc", "-q"]
    assert cli_main(["sweep", *tiny]) == 0
    out = capsys.readouterr().out
    why = [ln.strip() for ln in out.splitlines() if ln.strip().startswith("why:")]
    assert len(why) == 1 and "an integrator, like the dc-motor's angle" in why[0], out
    assert "not stationary" in why[0] and "qsid sweep --system boeing747" in why[0]
    assert cli_main(["sweep", "--system", "boeing747", *tiny]) == 0
    assert "why:" not in capsys.readouterr().out  # a stable plant: no such sentence


def test_the_default_summary_says_why_theorem1_does_not_apply_and_where_it_does():
    from app.frames.cache import SharedCache
    from app.frames.compute import iter_frames
    from app.frames.summary import summary_markdown

    frame = list(iter_frames(Values(**SMALL, mpc_steps=15), SharedCache()))[-1]
    s = summary_markdown(frame)
    line = next(ln for ln in s.splitlines() if "unit circle (integrator)" in ln)
    assert "wander, like the dc-motor's angle" in line and "not stationary" in line and "boeing747" in line
