"""Every lesson's claims, asserted on the numbers the dashboard computes for its settings
(lesson -> Values -> the dashboard's settings path -> the engine), and the lesson selector."""

from __future__ import annotations

import numpy as np
import pytest

from app.dashboard.frames import full_row
from app.dashboard.lessons import LESSONS, get_lesson, lesson_names, lesson_values
from app.dashboard.settings import LABELS, estimators, resolve_system, sweep_config
from qsid_core import Experiment
from qsid_core.sweep import fit_slope
from support import HANG_S, ROOT, Tab

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
    with pytest.raises(KeyError, match="unknown lesson 'nope'; choose one of fig1"):
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
    assert after == fresh, {k: (getattr(fresh, k), getattr(after, k)) for k in fresh.__dataclass_fields__
                            if getattr(fresh, k) != getattr(after, k)}


def test_each_controls_folder_is_built_once(tab):
    """A folder used by several controls used to be added again per control (an empty duplicate showed)."""
    from app.dashboard.controls import CONTROLS

    names = [c.folder for c in CONTROLS if c.folder]
    gui = tab.session.client.gui
    labels = [getattr(h, "label", None) for h in gui._container_handle_from_uuid.values()] \
        if hasattr(gui, "_container_handle_from_uuid") else None
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

    out = subprocess.run([sys.executable, "-m", "app.dashboard", "--lesson", "nope"], cwd=ROOT,
                         capture_output=True, text=True, timeout=HANG_S)
    assert out.returncode == 2 and out.stderr.strip().count("\n") == 0
    assert "unknown lesson 'nope'; choose one of fig1" in out.stderr
    app = DashboardApp(host="127.0.0.1", port=0, workers=0, lesson="bound")
    try:
        t = Tab(app).wait()
        assert t.controls["lesson"].value == "bound" and "The ultimate bound" in t.controls.lesson_text.content
        assert t.frame.system.name == "dc-motor" and t.frame.bits == 8
        t.close()
    finally:
        app.stop()
