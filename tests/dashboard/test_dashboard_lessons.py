"""Every lesson's claims, asserted on the numbers the dashboard computes for its settings
(lesson -> Values -> the dashboard's settings path -> the engine), and the lesson selector."""

from __future__ import annotations

import numpy as np
import pytest
from support import HANG_S, ROOT, Tab

from app.figures import registry
from app.frames.frame import full_row
from app.lessons.table import LESSONS, get_lesson, lesson_names, lesson_values
from app.settings.config import sweep_config
from app.settings.values import resolve_system
from qsid_core import Experiment
from qsid_core.studies import fit_slope

# slow: computes every lesson at its own (often paper-scale) settings
pytestmark = pytest.mark.slow

_EX: dict = {}


def experiment(name: str, **over) -> Experiment:
    """The engine experiment the dashboard builds for lesson ``name`` (plus panel changes ``over``)."""
    key = (name, tuple(sorted(over.items())))
    if key not in _EX:
        v = lesson_values(name).replace(**over)
        _EX[key] = Experiment(sweep_config(v, resolve_system(v).system))
    return _EX[key]


def rows(ex: Experiment, est: str, bits) -> dict:
    return {b: full_row(ex, est, b, ex.closed_loops(b, est)) for b in bits}


def spread(ex: Experiment, b: int) -> float:
    """Mean over realizations of the largest distance of an LS closed loop from the true-model loop."""
    x = ex.closed_loops(b, "ls").states
    xt = ex.true_model_loop().states[0]
    return float(np.nanmean(np.max(np.linalg.norm(x - xt, axis=-1), axis=1)))


def test_every_lesson_is_short_and_its_settings_are_valid():
    assert len(LESSONS) >= 7 and len(set(lesson_names())) == len(lesson_names())
    for les in LESSONS:
        n = les.text.count(". ") + 1
        assert 2 <= n <= 5, (les.name, n)
        v = lesson_values(les.name)
        sweep_config(v, resolve_system(v).system)  # the dashboard accepts it
    with pytest.raises(KeyError, match="unknown lesson 'nope'; choose one of start, fig1"):
        get_lesson("nope")


@pytest.mark.slow
def test_fig1_letter_settings_0p3_per_bit_faded_theorem_loops_close_in():
    ex = experiment("fig1")
    c = ex.config
    assert (c.trajectories, c.steps, c.realizations, c.quantizer.guard) == (200, 1000, 50, False)
    bits = range(4, 13)
    r = {b: ex.identification(b, "ls") for b in bits}
    for err in ("err_A", "err_B"):
        s = fit_slope(list(bits), [getattr(r[b], err).mean() for b in bits])
        assert -0.36 <= s <= -0.26, (err, s)
    assert not any(ex.assumptions(b).theorem1_holds for b in (2, 4, 6))
    assert spread(ex, 2) > spread(ex, 4) > spread(ex, 6)


@pytest.mark.slow
def test_fig2_boeing_cost_approaches_true_cost():
    ex = experiment("fig2")
    e = {b: ex.identification(b, "ls").err_A.mean() for b in range(2, 17)}
    coarse, fine = range(2, 7), range(8, 17)
    assert -0.65 <= fit_slope(list(coarse), [e[b] for b in coarse]) <= -0.45
    assert -0.36 <= fit_slope(list(fine), [e[b] for b in fine]) <= -0.26
    true = float(ex.true_model_loop().cost[0])
    gap = {b: abs(float(np.nanmean(ex.closed_loops(b, "ls").cost)) - true) / true for b in fine}
    assert max(gap.values()) < 1e-4, gap


@pytest.mark.slow
def test_theorem1_ls_on_the_line_where_hypotheses_hold():
    ex = experiment("theorem1")
    holds = [b for b in range(1, 17) if ex.assumptions(b).theorem1_holds]
    assert holds and max(holds) < 16
    fine = [b for b in range(1, 17) if b not in holds]
    assert all(not ex.assumptions(b).large_data and ex.assumptions(b).bcls_holds for b in fine)  # finite data only
    for b in holds:
        assert ex.identification(b, "ls").err_A.mean() == pytest.approx(ex.theory(b).err_A, rel=0.10), b


def test_why_dither_bcls_removes_known_noise_only_with_dither():
    d = experiment("dither")
    n = experiment("dither", dither="none")
    assert d.identification(3, "bcls").err_A.mean() < 0.05 and d.identification(3, "ls").err_A.mean() > 0.7
    assert n.identification(3, "bcls").err_A.mean() > 0.5
    assert d.assumptions(3).bcls_holds and not n.assumptions(3).bcls_holds


@pytest.mark.slow
def test_data_length_more_finite_data_flags_at_the_small_size():
    small = experiment("data-length")
    big = experiment("data-length", trajectories=200, steps=1000)
    fs = [b for b in range(1, 17) if not small.assumptions(b).large_data]
    fb = [b for b in range(1, 17) if not big.assumptions(b).large_data]
    assert fs == list(range(min(fs), 17)) and min(fs) < min(fb)
    assert small.identification(16, "ls").err_A.mean() > 10 * small.theory(16).err_A


def test_saturation_many_saturated_steps_and_loops_converge():
    ex = experiment("saturation")
    r = rows(ex, "ls", [8])[8]
    assert r["saturated_steps"]["steps"] >= 0.1 * r["saturated_steps"]["of_steps"]
    x0 = np.linalg.norm([5, 5, 0, 0])
    assert r["final_state_norm"]["max"] < 0.1 * x0


def test_ultimate_bound_realized_above_letters_and_loops_end_below_both():
    ex = experiment("bound")
    rs = rows(ex, "ls", range(1, 17))
    for b, r in rs.items():
        if r["ultimate_bound"] is not None and r["ultimate_bound_realized"]["median"] is not None:
            assert r["ultimate_bound_realized"]["median"] > r["ultimate_bound"], b
    r8 = rs[8]
    assert r8["final_state_norm"]["max"] < min(r8["ultimate_bound"], r8["ultimate_bound_realized"]["median"])


# ----- the selector in a served tab ---------------------------------------------------------


def test_selecting_a_lesson_sets_the_controls_and_shows_its_text(tab):
    c = tab.controls
    assert not c.lesson_text.visible and c["lesson"].options[0] == "(none)"
    tab.set(lesson="saturation")
    les = get_lesson("saturation")
    assert c.lesson_text.visible and les.title in c.lesson_text.content and les.text in c.lesson_text.content
    assert c["system"].value == "boeing747" and c["x0"].value == "5, 5, 0, 0" and c["u_max"].value == 0.2
    assert (c["bits"].value, c["mpc_steps"].value, c["trajectories"].value) == (8, 100, 50)
    f = tab.frame
    assert f.system.name == "boeing747" and f.bits == 8 and tuple(f.x0) == (5, 5, 0, 0) and tab.error is None
    r = f.rows["LS"][8]
    assert r["saturated_steps"]["steps"] >= 0.1 * r["saturated_steps"]["of_steps"]  # what the text says
    tab.set(lesson="(none)")
    assert not c.lesson_text.visible and c["system"].value == "boeing747"  # the panel stays as it is


@pytest.mark.slow
def test_a_lesson_does_not_depend_on_the_lessons_opened_before(tab):
    """Walkthrough repro: saturation (|u| <= 0.2), then fig2 kept the bound 0.2 (50/50 loops saturated)."""
    tab.set(lesson="fig2")
    fresh = tab.frame.values
    tab.set(lesson="saturation")
    assert tab.controls["u_max"].value == 0.2
    tab.set(u_max=0.3, realizations=7)  # and the teacher changed more by hand
    tab.set(lesson="fig2")
    after = tab.frame.values
    assert after == fresh, {
        k: (getattr(fresh, k), getattr(after, k))
        for k in fresh.__dataclass_fields__
        if getattr(fresh, k) != getattr(after, k)
    }


def test_each_controls_folder_is_built_once(tab):
    """A folder used by several controls used to be added again per control (an empty duplicate showed)."""
    from app.dashboard.controls import CONTROLS

    names = [c.folder for c in CONTROLS if c.folder]
    gui = tab.session.client.gui
    labels = (
        [getattr(h, "label", None) for h in gui._container_handle_from_uuid.values()]
        if hasattr(gui, "_container_handle_from_uuid")
        else None
    )
    if labels is None:
        pytest.skip("this viser keeps no container registry to count folders in")
    for name in set(names):
        assert labels.count(name) == 1, (name, labels.count(name))


def test_a_bad_input_after_a_lesson_is_explained_and_the_view_stays(tab):
    tab.set(lesson="bound")
    view = tab.session.portrait.view
    tab.set(input_amplitude=-1.0)
    assert "input amplitude must be a positive number" in tab.error
    assert tab.session.portrait.view is view


@pytest.mark.slow
def test_dashboard_starts_on_a_lesson_and_rejects_a_bad_name():
    import subprocess
    import sys

    from app.dashboard import DashboardApp

    out = subprocess.run(
        [sys.executable, "-m", "app.dashboard", "--lesson", "nope"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=HANG_S,
    )
    assert out.returncode == 2 and out.stderr.strip().count("\n") == 0
    assert "unknown lesson 'nope'; choose one of start, fig1" in out.stderr
    app = DashboardApp(host="127.0.0.1", port=0, workers=0, lesson="bound")
    try:
        t = Tab(app).wait()
        assert t.controls["lesson"].value == "bound" and "The ultimate bound" in t.controls.lesson_text.content
        assert t.frame.system.name == "dc-motor" and t.frame.bits == 8
        t.close()
    finally:
        app.stop()


# ----- text against marks, the new lessons, guided lessons --------------------------------


def _ls_rows(ex: Experiment, bits) -> list:
    from app.frames.frame import row
    from qsid_core.studies import summary_row

    return [
        row(summary_row(ex.system.n, ex.identification(b, "ls"), ex.theory(b), None, assumptions=ex.assumptions(b)))
        for b in bits
    ]


def _line(fig, name: str, axis: str) -> set:
    """The b where the trace ``name`` on x axis ``axis`` is drawn."""
    return {
        b for t in fig.data if t.name == name and (t.xaxis or "x") == axis for b, y in zip(t.x, t.y) if y is not None
    }


def test_letters_lessons_use_ls_only():
    assert get_lesson("fig1").settings["identification"] == "LS"
    assert get_lesson("fig2").settings["identification"] == "LS"


def test_fig2_text_note_and_marks_agree():
    """fig2 at b = 2..6: the text says Â sits on Theorem 1's dashed line and B̂ does not (clipping); the plot
    draws the A line dashed there (LS within 5 %), the B line faded, and the note names the clipping."""
    from app.figures.error_vs_bits import error_figure

    ex = experiment("fig2")
    rows = _ls_rows(ex, range(1, 9))
    fig = error_figure({"LS": rows})
    text = get_lesson("fig2").text
    assert "on Theorem 1's dashed line" in text and "B̂ is not on its line" in text and "clips" in text
    assert set(range(2, 7)) <= _line(fig, "Theorem 1", "x")
    for r in rows:
        if 2 <= r["bits"] <= 6:
            assert r["err_A"]["mean"] == pytest.approx(r["err_A_theory"], rel=0.05), r["bits"]
            assert not r["assumptions"]["theorem1_holds_B"] and not r["assumptions"]["fits_B"]
    assert not set(range(2, 7)) & _line(fig, "Theorem 1", "x2")
    assert set(range(2, 7)) <= _line(fig, "Theorem 1 (hypotheses fail)", "x2")
    note = " ".join(a.hovertext or "" for a in fig.layout.annotations)  # the note's sentences, on hover
    assert "overload: the per-channel data range (min/max, no guard band) clips" in note and "for B̂" in note
    # the theory lines are drawn last: above the data, never hidden
    kinds = [t.name or "" for t in fig.data]
    assert max(i for i, k in enumerate(kinds) if k == "LS") < min(
        i for i, k in enumerate(kinds) if k.startswith("Theorem 1")
    )
    # the slope is read out (next to the letter's numbers only on the letter's DC motor: test_dashboard_truth)
    titles = " ".join(a.text for a in fig.layout.annotations)
    assert "slope −" in titles


def test_dither_lesson_at_b12_names_clipping():
    from app.figures.error_vs_bits import error_figure

    ex = experiment("dither")
    rows = _ls_rows(ex, (3, 12))
    a12 = rows[1]["assumptions"]
    assert abs(100 * a12["overload_fraction"] - 0.05) < 0.01 and not a12["no_overload"]
    fig = error_figure({"LS": rows})
    hover = " ".join(a.hovertext or "" for a in fig.layout.annotations)
    assert "overload: the range ±20 (no guard band) clips 0.053 % of the samples" in hover
    assert "not the data length, sets the error floor" in hover
    text = get_lesson("dither").text
    assert "clips 0.05 % of the samples" in text and "not the data length, sets this floor" in text
    e12 = ex.identification(12, "ls").err_A.mean()
    assert 1.5e-4 < e12 < 2.5e-4  # "level off near 2e-4"


def test_one_cell_lesson_plain_fails_dither_rescues():
    """Inputs |u| <= 1 in cells 5 wide: without dither LS and BCLS miss A and B by > 60 %; with subtractive
    dither BCLS is within 5 %; the quantizer view's error is a sawtooth of u without dither, independent with."""
    from qsid_core.quantization.quantizer_demo import channel_demo

    plain = experiment("one-cell")
    dith = experiment("one-cell", dither="subtractive")
    assert plain.config.quantizer.dither == "none"
    for est in ("ls", "bcls"):
        i = plain.identification(4, est)
        assert i.err_A.mean() > 0.6 and i.err_B.mean() > 0.6, est
    bc = dith.identification(4, "bcls")
    assert bc.err_A.mean() < 0.05 and bc.err_B.mean() < 0.05
    assert np.abs(plain.data.inputs).max() <= 1.0 and bc.eps[plain.system.n] == pytest.approx(5.0)
    d = channel_demo(plain, lesson_values("one-cell").view_channel, 4)
    assert d.label == "u1" and d.cell_dependence_plain > 0.9 and d.cell_dependence_dithered < 0.02


def test_choosing_a_lesson_brings_its_plot_forward(tab):
    views = tab.session.views
    tab.set(lesson="bound")
    assert views.shown == "Control" and views.group.value == "Control"
    assert all(h.visible for h in views.groups["Control"])
    assert not any(h.visible for g in ("Identification", "Quantizer") for h in views.groups[g])
    control = [v.name for v in registry.VIEWS if v.tab == "Control"]
    assert min(control, key=lambda n: views.plots[n].order) == "bound"
    assert "**Bound lesson, b = 8**" in tab.summary and "‖x0‖" in tab.summary
    tab.set(lesson="one-cell")
    assert views.shown == "Quantizer" and views.plots["quantizer"].visible and not views.plots["bound"].visible
    assert views.channel.value == "u: elevator"
    tab.set(lesson="fig1")
    assert views.shown == "Identification" and views.group.value == "Identification"
    assert min(control, key=lambda n: views.plots[n].order) == control[0]  # the Control tab back in order


@pytest.mark.parametrize("name, tab_name", [("fig1", "Identification"), ("bound", "Control")])
def test_lesson_flag_opens_on_its_tab(name, tab_name):
    from support import Tab

    from app.dashboard.server import DashboardApp

    a = DashboardApp(host="127.0.0.1", port=0, workers=0, lesson=name)
    try:
        t = Tab(a)
        assert t.session.views.shown == tab_name and t.session.views.group.value == tab_name
        t.close()
    finally:
        a.stop()


def test_the_person_picks_any_group_and_a_lesson_picks_its_own(tab):
    """The "show" dropdown reveals one group (its inputs and plots) and hides the rest; nothing else changes."""
    views = tab.session.views
    gen = tab.session.generation
    for name in registry.TABS:
        views.group.value = name
        assert views.shown == name
        for group, handles in views.groups.items():
            assert all(h.visible == (group == name) for h in handles), (name, group)
    assert tab.session.generation == gen  # picking a group is not a change of settings: nothing recomputed
    views.show("no such group")
    assert views.shown == registry.TABS[0] and views.group.value == registry.TABS[0]


def test_fig1_and_theorem1_text_agree_with_marks():
    """fig1 says Theorem 1's line is faded (integrator): no dashed line, the note says why. theorem1 says
    LS sits on the dashed line where every hypothesis holds: the dashed A line is drawn exactly there or
    where LS is within 5 % of it, and it is faded at fine b."""
    from app.figures.error_vs_bits import error_figure

    assert "Theorem 1's line is faded: the motor angle is an integrator" in get_lesson("fig1").text
    fig = error_figure({"LS": _ls_rows(experiment("fig1"), range(4, 13))})
    assert not _line(fig, "Theorem 1", "x") and not _line(fig, "Theorem 1", "x2")
    assert "integrator" in " ".join(a.hovertext or "" for a in fig.layout.annotations)  # the note, on hover
    ex = experiment("theorem1")
    rows = _ls_rows(ex, range(1, 17))
    fig = error_figure({"LS": rows})
    drawn = _line(fig, "Theorem 1", "x")
    holds = {r["bits"] for r in rows if r["assumptions"]["theorem1_holds_A"]}
    assert holds and holds <= drawn and 16 not in drawn and 16 in _line(fig, "Theorem 1 (hypotheses fail)", "x")
    for r in rows:
        if r["bits"] in drawn:
            assert r["err_A"]["mean"] == pytest.approx(r["err_A_theory"], rel=0.10), r["bits"]


def _gain(loops) -> float:
    return float(np.mean([np.linalg.norm(np.asarray(k)) for k in loops.gains]))


@pytest.mark.slow
def test_bits_needed_explains_why_b1_settles_and_b2_does_not():
    """The sentence: b = 1 settles more loops than b = 2 (every loop against few), its MPC barely acting (‖K̂‖
    about a fifth of the true model's) while b = 2's acts harder. (The gains are on no plot: the text names none.)"""
    ex = experiment("bits-needed")
    one, two = ex.closed_loops(1, "ls"), ex.closed_loops(2, "ls")
    assert one.outcome_counts()["converged"] == len(one.gains)
    assert two.outcome_counts()["converged"] <= 0.1 * len(two.gains)
    true = float(np.linalg.norm(np.asarray(ex.true_model_loop().gains[0])))
    assert abs(_gain(one) - 0.24) < 0.01 and abs(_gain(two) - 0.66) < 0.01 and abs(true - 1.08) < 0.01
    assert np.max(np.abs(np.linalg.eigvals(ex.system.A))) < 1  # the Boeing is stable on its own
    assert _gain(one) < 0.3 * true and _gain(one) < _gain(two)  # "barely acts", "acts harder"
    text = get_lesson("bits-needed").text
    assert "b = 1 settles more loops than b = 2" in text and "‖K̂‖" not in text


@pytest.mark.slow
def test_feedback_lesson_explains_b1_below_the_floor():
    """The sentence: b = 1's steady-state error is below the true model's because its inputs are ~10x smaller."""
    ex = experiment("feedback")
    one, tl = ex.closed_loops(1, "ls"), ex.true_model_loop()
    assert np.mean(one.steady_state_error) < float(tl.steady_state_error[0])
    ratio = np.sqrt(np.nanmean(np.asarray(tl.inputs) ** 2)) / np.sqrt(np.nanmean(np.asarray(one.inputs) ** 2))
    assert 7 < ratio < 13, ratio
    assert "inputs ~10× smaller than the true model's" in get_lesson("feedback").text
