"""A nonlinear plant in the dashboard: the panel switches to its inputs and back, the Koopman frames are
drawn in the Nonlinear group, bad input is one line with the last view kept, the exports and the command line
describe what was computed (the command is parsed and run by the real CLI)."""

from __future__ import annotations

import json
import shlex

import pytest
from support import SMALL

from app.figures import registry
from app.frames.compute import iter_frames
from app.settings.config import koopman_config
from app.settings.values import LINEAR_ONLY, NL_INTERACTIVE, NONLINEAR_ONLY, SYSTEM_CHOICES, Values
from qsid_core.studies import KoopmanExperiment, run_koopman_sweep

#: a small nonlinear tab: every b's models and loops in a few seconds
NL_SMALL = dict(trajectories=20, steps=50, realizations=2, mpc_steps=30, horizon=8)


def test_the_system_dropdown_offers_the_nonlinear_presets():
    assert {"van-der-pol", "duffing", "pendulum"} <= set(SYSTEM_CHOICES)


def test_the_frames_rows_equal_the_command_lines_sweep():
    v = Values(system="pendulum", bits=3, lifting="poly:2", state_amplitude=2.0, **NL_SMALL)
    frames = list(iter_frames(v))
    assert [f.stage for f in frames][0] == "current" and frames[-1].complete
    cfg, ests = koopman_config(v)
    assert ests == ("ls", "bcls")
    import dataclasses

    for e, lab in (("ls", "LS"), ("bcls", "BCLS")):
        ref = run_koopman_sweep(dataclasses.replace(cfg, estimator=e, bits=(2, 3, 5)))
        for r in ref.rows:
            got = frames[-1].rows[lab][r["bits"]]
            assert got["err_G"] == r["err_G"] and got["closed_loop_outcomes"] == r["closed_loop_outcomes"]


def test_a_newer_change_stops_the_frames_after_the_current_b():
    v = Values(system="van-der-pol", bits=4, **NL_SMALL)
    stop = []
    frames = iter_frames(v, should_stop=lambda: bool(stop))
    first = next(frames)
    assert first.stage == "current" and set(first.rows["LS"]) == {4}
    stop.append(1)
    assert list(frames) == []


def test_the_cache_is_shared_by_a_b_change():
    cache: dict = {}
    v = Values(system="van-der-pol", bits=4, **NL_SMALL)
    list(iter_frames(v, cache))
    n = len(cache)
    list(iter_frames(v.replace(bits=6), cache))
    assert len(cache) == n  # a b change computes nothing new


@pytest.mark.parametrize(
    "change,words",
    [
        ({"lifting": "poly:0"}, "degree must be 1..8"),
        ({"lifting": "fourier:3"}, "unknown dictionary"),
        ({"trajectories": 1, "steps": 10, "lifting": "poly:4"}, "cannot fit"),
    ],
)
def test_bad_nonlinear_input_is_one_line_and_the_view_is_kept(tab, change, words):
    tab.set(system="van-der-pol", **NL_SMALL)
    assert tab.error is None and tab.frame.kind == "koopman"
    kept = tab.frame
    tab.set(**change)
    assert words in tab.error and "\n" not in tab.error.split("  \n")[0] and tab.frame is kept


def test_a_vector_field_that_fails_is_one_line():
    from qsid_core import QsidError
    from qsid_core.plant import NonlinearSystem
    from qsid_core.studies import KoopmanConfig

    def bad(x, u):
        return x * float("nan")

    def raises(x, u):
        raise ZeroDivisionError("no")

    for f, words in ((bad, "NaN or inf"), (raises, "raised ZeroDivisionError")):
        s = NonlinearSystem("mine", f, 2, 1)
        with pytest.raises(QsidError, match=words):
            KoopmanExperiment(KoopmanConfig(system=s, trajectories=3, steps=5, realizations=1)).data()


def test_the_panel_switches_to_a_nonlinear_plant_and_back(tab):
    c = tab.controls
    linear = {k: getattr(tab.frame.values, k) for k in NL_INTERACTIVE}
    tab.set(system="van-der-pol")
    v = tab.frame.values
    assert tab.frame.kind == "koopman" and {k: getattr(v, k) for k in NL_INTERACTIVE} == {
        k: linear[k] for k in NL_INTERACTIVE
    }  # the small test size was the person's own: kept
    assert all(not c[n].visible for n in LINEAR_ONLY) and all(c[n].visible for n in NONLINEAR_ONLY)
    assert c.theory_note is not None and c.theory_note.visible  # the Theory tab says why it is empty
    assert tab.session.views.shown == "Nonlinear"
    assert tuple(tab.session.views.group.options) == registry.KOOPMAN_TABS
    for name in (v.name for v in registry.KOOPMAN_VIEWS):
        assert tab.session.plots[name].figure.layout.xaxis.title.text is not None
    assert "do not apply" in tab.summary and "BCLS" in tab.summary
    tab.set(system="dc-motor")
    assert getattr(tab.frame, "kind", "linear") != "koopman" and tab.session.views.shown == "Identification"
    assert all(c[n].visible for n in LINEAR_ONLY if n not in ("fixed_range", "axes")) and not any(
        c[n].visible for n in NONLINEAR_ONLY
    )
    assert not c.theory_note.visible


@pytest.mark.slow  # the whole interactive nonlinear tab, in-process
def test_interactive_defaults_are_set_when_the_panel_was_at_the_linear_ones(dashboard):
    from support import Tab

    t = Tab(dashboard)
    try:
        t.wait()
        t.controls["system"].value = "duffing"
        t.wait()
        v = t.frame.values
        assert {k: getattr(v, k) for k in NL_INTERACTIVE} == NL_INTERACTIVE and (v.horizon, v.mpc_steps) == (20, 200)
        t.set(system="dc-motor")
        assert (t.frame.values.trajectories, t.frame.values.realizations) == (50, 20)
    finally:
        t.close()


def test_command_line_exports_and_settings_of_a_nonlinear_tab(tab, tmp_path, capsys):
    from app.cli.main import main
    from app.frames.exports import command_lines, curves_csv, curves_json, frame_html
    from app.settings.files import settings_json, values_from_json

    tab.set(system="van-der-pol", lifting="poly:2", dither_seed=3, prediction_horizon=7, **NL_SMALL)
    f = tab.frame
    lines = command_lines(f.values)
    assert len(lines) == 2 and all("--system=van-der-pol" in ln and "--lifting=poly:2" in ln for ln in lines)
    assert "--estimator=bcls" in lines[1] and all("--prediction-horizon=7" in ln for ln in lines)
    argv = shlex.split(lines[1])[1:] + ["--bits=3", "--json", "-q"]
    assert main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["results"][0]["err_G"] == f.rows["BCLS"][3]["err_G"]
    assert out["results"][0]["prediction_error"] == f.rows["BCLS"][3]["prediction_error"]
    assert out["config"]["held_out"]["horizon"] == 7
    assert tab.session.plots["koopman-prediction"].figure.layout.yaxis.title.text == "prediction error, steps 1..7"
    assert out["results"][0]["closed_loop_outcomes"] == f.rows["BCLS"][3]["closed_loop_outcomes"]
    assert out["results"][0]["settled_offset"] == f.rows["BCLS"][3]["settled_offset"]
    csv_text = curves_csv(f)
    assert csv_text.splitlines()[0].startswith("estimator,bits,err_G_mean") and len(csv_text.splitlines()) == 33
    assert csv_text.splitlines()[0].endswith(",within_radius,settled_offset_median,settled_offset_max")
    assert json.loads(curves_json(f))["kind"] == "koopman"
    assert "koopman-error" in frame_html(f)
    back = values_from_json(settings_json(f.values))
    assert back == f.values


def test_no_nonlinear_view_is_built_for_a_linear_frame(tab):
    assert getattr(tab.frame, "kind", "linear") == "linear" and tab.session.ui.renderer._style[1] == "linear"
    assert tab.session.views.shown == "Identification" and tab.frame.values.trajectories == SMALL["trajectories"]


def test_the_server_prefills_a_nonlinear_start():
    from app.dashboard.lifecycle import prefill

    cache: dict = {}
    assert prefill(Values(system="van-der-pol", **NL_SMALL), cache) > 2 and cache


FIELD = """
import numpy as np

MODE = "ok"


def field(x, u):
    if MODE == "raise":
        raise ZeroDivisionError("no field here")
    if MODE == "nan":
        return x * np.nan
    return np.stack([x[:, 1], -np.sin(x[:, 0]) - 0.2 * x[:, 1] + u[:, 0]], axis=1)
"""


def test_a_plant_files_vector_field_in_the_panel_and_its_failures(tmp_path, monkeypatch):
    import importlib

    from support import Tab

    from app.dashboard import DashboardApp
    from app.frames.exports import command_lines
    from app.settings.files import values_for_plant_file

    (tmp_path / "qsid_test_field.py").write_text(FIELD)
    monkeypatch.syspath_prepend(str(tmp_path))
    plant = tmp_path / "swing.toml"
    plant.write_text('vector_field = "qsid_test_field:field"\nn = 2\nm = 1\nx0 = [1.0, 0.0]\n')
    v, notes = values_for_plant_file(plant, Values())
    assert (
        v.system == str(plant) and notes == [] and (v.realizations, v.horizon) == (NL_INTERACTIVE["realizations"], 20)
    )
    app = DashboardApp(host="127.0.0.1", port=0, workers=0, settings=v.replace(**NL_SMALL))
    try:
        t = Tab(app).wait()
        assert t.error is None and t.frame.kind == "koopman" and str(plant) in t.controls["system"].options
        assert all(f"--system={plant}" in ln for ln in command_lines(t.frame.values))
        kept = t.frame
        mod = importlib.import_module("qsid_test_field")
        for seed, mode, words in ((7, "raise", "raised ZeroDivisionError: no field here"), (8, "nan", "NaN or inf")):
            monkeypatch.setattr(mod, "MODE", mode)
            t.set(data_seed=seed)
            assert words in t.error and "Traceback" not in t.error and t.frame is kept
        t.close()
    finally:
        app.stop()


def test_a_plant_file_that_cannot_load_is_one_line(tmp_path):
    from app.settings.files import values_for_plant_file
    from app.settings.values import InputError

    plant = tmp_path / "gone.toml"
    plant.write_text('vector_field = "no_such_module_qsid:field"\nn = 2\nm = 1\n')
    with pytest.raises(InputError, match="cannot be loaded"):
        values_for_plant_file(plant, Values())


def test_leaving_a_linear_lesson_for_a_nonlinear_plant_takes_the_nonlinear_size():
    from app.lessons.table import lesson_values
    from app.settings.values import switch_defaults

    fig1 = lesson_values("fig1")  # the letter's 200 x 1000, 50 realizations
    moved = switch_defaults(fig1.replace(system="van-der-pol"), "van-der-pol", True, also=fig1)
    assert {k: moved[k] for k in NL_INTERACTIVE} == NL_INTERACTIVE
    mine = fig1.replace(system="van-der-pol", trajectories=77)  # a value the person chose stays
    assert "trajectories" not in switch_defaults(mine, "van-der-pol", True, also=fig1)
    back = switch_defaults(
        lesson_values("koopman").replace(system="dc-motor"), "van-der-pol", False, lesson_values("koopman")
    )
    assert (back["trajectories"], back["realizations"]) == (50, 20)


@pytest.mark.parametrize("guard", [False, True])
def test_the_summary_and_the_error_plot_agree_on_the_large_data_limit(guard):
    from app.frames.render import build_figures
    from app.frames.summary import summary_markdown

    v = Values(system="van-der-pol", bits=3, guard=guard, **NL_SMALL)
    frame = list(iter_frames(v))[-1]
    fig = build_figures(frame, ("koopman-error",))["koopman-error"]
    drawn = any(t.name == "LS large-data limit" for t in fig.data)
    notes = [a.text for a in fig.layout.annotations if a.text.startswith("no large-data limit")]
    line = next(ln for ln in summary_markdown(frame).split("  \n") if ln.startswith("LS's large-data limit"))
    assert drawn == guard and bool(notes) == (not guard)
    assert ("not drawn" in line) == (not guard)
    if not guard:  # without the guard band dither pushes samples past the data's range at every b
        assert "samples past the range at every b" in line and "tick the guard band" in notes[0]


def test_the_summary_gives_the_loops_within_radius_as_a_share_next_to_the_radius():
    """The summary said "within radius 5", read as a radius of 5: it meant 5 of 5 loops within radius 0.1."""
    from app.frames.summary import summary_markdown

    v = Values(system="van-der-pol", bits=3, **NL_SMALL)
    frame = list(iter_frames(v))[-1]
    text = summary_markdown(frame)
    for lab in frame.labels:
        r = frame.rows[lab][3]
        want = f"{r['within_radius']}/{r['realizations']} within radius {v.converged_radius:g}"
        assert want in text, text
