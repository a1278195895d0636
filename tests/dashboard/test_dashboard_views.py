"""What a tab shows, without a server: frames (app.dashboard.session.iter_frames), the views
(app.figures), the 3-D scene arrays, the summary and what the renderer redraws."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from app.dashboard.session import iter_frames
from app.figures import move_current_bits
from app.figures.palette import COLORS, rgb, vertex_rgb
from app.figures.phase_scene import CLIP, SPHERE_CAP, scene_view
from app.figures.registry import VIEWS
from app.frames.cache import SharedCache
from app.frames.render import Renderer, build_figures
from app.frames.summary import summary_markdown
from app.settings.config import sweep_config
from app.settings.values import ALL_BITS, InputError, Values
from qsid_core import Experiment
from qsid_core.errors import QsidError

SMALL = dict(trajectories=10, steps=60, realizations=4, mpc_steps=15)
NAMES = (
    "error",
    "eigen",
    "timeseries",
    "cost",
    "bits",
    "bound",
    "norm_time",
    "residual",
    "quantizer",
    "datalength",
    "bandwidth",
    "portraits",
)


def frames(v: Values, cache=None):
    return list(iter_frames(v, cache if cache is not None else SharedCache()))


# ----- frames, scene, figures, summary ------------------------------------------------------


def test_frames_current_b_first_then_all_curves():
    fr = list(iter_frames(Values(bits=6, **SMALL), SharedCache(), chunk=5, min_interval=0.0))
    assert fr[0].stage == "current" and fr[0].bits == 6 and set(fr[0].rows["LS"]) == {6}
    assert [f.stage for f in fr[1:]] == ["curves"] * 3
    assert [f.done for f in fr] == [1, 6, 11, 16] and fr[-1].complete
    assert set(fr[-1].rows["LS"]) == set(ALL_BITS) and set(fr[-1].rows["BCLS"]) == set(ALL_BITS)
    assert fr[0].labels == ("LS", "BCLS")
    # the rows are the engine's own summary rows
    ex = Experiment(sweep_config(fr[0].values, fr[0].system))
    assert fr[-1].rows["LS"][3]["err_A"]["mean"] == pytest.approx(float(ex.identification(3).err_A.mean()))


def test_frames_stop_when_newer_settings_arrive():
    newer = threading.Event()
    it = iter_frames(Values(**SMALL), SharedCache(), should_stop=newer.is_set, chunk=3, min_interval=0.0)
    assert next(it).stage == "current" and next(it).stage == "curves"
    newer.set()
    assert list(it) == []


def test_engine_errors_come_out_as_plain_words():
    unstable = Values(system="custom", a_text="1.5 0\n0 1.2", b_text="1; 1", trajectories=5, steps=1000)
    with pytest.raises(QsidError, match="spectral radius of A is 1.5"):
        frames(unstable)
    with pytest.raises(InputError, match="Custom system"):
        frames(Values(system="custom", a_text="1 2", b_text="1"))


def test_scene_view_shapes_scale_and_sphere():
    fr = frames(Values(system="boeing747", bits=12, **SMALL))
    f = fr[-1]
    sv = scene_view(f, "u, q, theta")
    assert sv.segments.shape == (2 * 4 * 15, 2, 3) and sv.segments.dtype == np.float32
    assert sv.colors.shape == sv.segments.shape and sv.colors.dtype == np.uint8
    assert sv.true_segments.shape == (15, 2, 3)
    assert sv.axis_names == ("u", "q", "theta") and sv.polylines == 8
    ts = f.true_loop.states[0]
    assert sv.scale == pytest.approx(np.abs(ts[:, [0, 2, 3]]).max())
    np.testing.assert_allclose(sv.true_segments[0, 0], ts[0, [0, 2, 3]] / sv.scale, rtol=1e-6)
    np.testing.assert_allclose(sv.start, ts[0, [0, 2, 3]] / sv.scale)
    assert sv.delta == pytest.approx(f.theory.delta)
    assert sv.sphere_radius == pytest.approx(f.theory.delta / sv.scale)
    assert sv.sphere_capped == (sv.sphere_radius > SPHERE_CAP) and (sv.bound_circles.shape[0] > 0) != sv.sphere_capped
    assert np.abs(sv.segments).max() <= CLIP


def test_scene_view_hides_failed_and_clips_diverging_loops():
    f = frames(Values(bits=3, **SMALL))[0]
    st = f.loops["LS"].states
    st[0] = np.nan  # a failed realization (the engine writes NaN)
    st[1, 5:] = 1e9  # a diverging one
    sv = scene_view(f)
    assert sv.failed == 1 and sv.clipped == 1
    T = st.shape[1] - 1
    np.testing.assert_allclose(sv.segments[:T], np.broadcast_to(sv.start, (T, 2, 3)))
    assert np.isfinite(sv.segments).all() and np.abs(sv.segments).max() == pytest.approx(CLIP)


def test_figures_draw_partial_rows_and_move_the_marker():
    fr = list(iter_frames(Values(bits=5, **SMALL), SharedCache(), chunk=5, min_interval=0.0))
    figs = build_figures(fr[0])  # only the current b computed so far
    assert set(figs) == set(NAMES)
    xs = [x for tr in figs["error"].data for x in (tr.x or ())]
    assert 5 in xs and set(xs) <= {5, 6}  # one b (6 only on the -0.301/bit reference segment)
    partial = build_figures(fr[1])["error"]
    assert {x for tr in partial.data for x in (tr.x or ())} >= {1, 2, 3, 4, 5, 6}
    full = build_figures(fr[-1])
    marks = [s.x0 for s in full["error"].layout.shapes]
    assert marks == [5, 5]
    move_current_bits(full["error"], 9)
    assert [s.x0 for s in full["error"].layout.shapes] == [9, 9]
    move_current_bits(full["cost"], 9)  # the horizontal true-cost line stays
    assert sorted(str(s.x0) for s in full["cost"].layout.shapes) == ["0", "9"]
    eig = figs["eigen"]
    names = [t.name for t in eig.data]
    assert len(eig.data[names.index("eig LS")].x) == 4 * 3  # 4 realizations x 3 eigenvalues (LS)
    assert names.index("eig A (true)") < names.index("eig LS")  # the estimates are drawn over the true markers


def test_renderer_redraws_only_what_changed():
    cache = SharedCache()
    ren = Renderer()
    v = Values(**SMALL)
    out = [ren.render(f) for f in iter_frames(v, cache)]
    assert out[0].scene is not None and out[0].summary and "eigen" in out[0].figures
    assert set(out[-1].figures) == {"error", "cost", "bits", "bound", "residual", "portraits", "bandwidth"}
    err = ren.figures["error"]
    # a b change: new scene and eigenvalues; the curves are not rebuilt, only re-marked, once: the figure as
    # built is left as it is (other tabs may draw it) and pushed with its marker moved
    out = [ren.render(f) for f in iter_frames(v.replace(bits=8), cache)]
    assert out[0].scene is not None and "eigen" in out[0].figures
    moved = out[0].figures["error"]
    assert moved.wire.base is err.figure and [s.x0 for s in moved.layout.shapes] == [8, 8]
    assert [s.x0 for s in err.layout.shapes] == [v.bits, v.bits]
    assert all("error" not in r.figures for r in out[1:])  # marked at 8 already: not pushed again
    err = ren.figures["error"]
    # a Q change: same models, no new eigenvalue plot, new curves
    out = [ren.render(f) for f in iter_frames(v.replace(bits=8, log_q=(1.0, -1.0, -1.0)), cache)]
    assert "eigen" not in out[0].figures
    assert out[-1].figures["cost"] is not None and ren.figures["error"] is not err


def test_summary_lists_eps_errors_overload_and_failures():
    f = frames(Values(bits=2, **SMALL))[-1]
    text = summary_markdown(f)
    assert "b = **2** bits" in text and "ε states: angle" in text and "ε inputs: voltage" in text
    assert (
        "overload:" in text
        and "predicted effect of the clipped samples on Â" in text
        and "| LS |" in text
        and "| BCLS |" in text
        and "Thm 1" in text
    )
    assert "MPC cost with the true model" in text
    lp = f.loops["LS"]
    lp.failure[0], lp.messages[0] = "dare", "DARE has no stabilizing solution for the identified model"
    f.rows["LS"][2]["mpc_cost"]["failed"] = 1
    f.rows["LS"][2]["mpc_cost"]["failures"] = {"dare": 1}
    assert f.rows["LS"][2]["closed_loop_outcomes"] == {"converged": 4, "bounded": 0, "diverged": 0, "failed": 0}
    assert "all 4 converged" in text
    f.rows["LS"][2]["closed_loop_outcomes"] = {"converged": 2, "bounded": 1, "diverged": 0, "failed": 1}
    f.rows["LS"][2]["closed_loop_spectral_radius"] = {"median": 0.5, "max": 1.25}
    text = summary_markdown(f)
    assert "**2/4 did not converge**: 2 converged, 1 bounded, 1 failed (ρ(A − BK̂) up to 1.2500)" in text
    assert "LS MPC: DARE has no stabilizing solution" in text and "none failed" not in text


def test_a_failed_identification_is_reported_and_not_drawn():
    f = frames(Values(bits=3, **SMALL))[-1]
    ident = f.idents["LS"]
    ident.A_hat[1] = np.nan
    ident.failed = np.array([False, True, False, False])
    ident.notes = ["identification failed: singular data"]
    f.rows["LS"][3]["ident_failures"] = 1
    eig = build_figures(f, ("eigen",))["eigen"]
    assert len(next(t for t in eig.data if t.name == "eig LS").x) == 3 * 3  # 3 good realizations x 3 eigenvalues
    assert "LS identification failed in 1 of 4 realizations" in summary_markdown(f)


# ----- registry and palette ------------------------------------------------------------------


def test_every_registered_view_is_built():
    fr = frames(Values(bits=5, **SMALL))
    names = [v.name for v in VIEWS]
    assert names == list(NAMES) and len(set(names)) == len(names)
    figs = build_figures(fr[-1])
    assert list(figs) == names
    assert all(len(f.data) > 0 for n, f in figs.items() if n not in ("datalength", "bandwidth"))  # on demand


def test_a_new_view_is_one_registry_entry(monkeypatch):
    """Registering one more View is all it takes for the renderer to draw it."""
    import plotly.graph_objects as go

    from app.figures import registry
    from app.figures.view import CURVES, View

    def count(frame):
        rows = frame.series()["LS"]
        return go.Figure(go.Bar(x=[r["bits"] for r in rows], y=[r["bcls_fallbacks"] for r in rows]))

    monkeypatch.setattr(registry, "VIEWS", registry.VIEWS + (View("fallbacks", 0.5, CURVES, count),))
    out = [Renderer().render(f) for f in iter_frames(Values(**SMALL), SharedCache())]
    assert list(out[-1].figures["fallbacks"].data[0].x) == list(ALL_BITS)


def test_one_palette_for_plots_and_the_3d_scene():
    f = frames(Values(bits=6, **SMALL))[-1]
    sv = scene_view(f)
    T = 15
    # per-vertex colours go to the screen as linear light: the scene sends the palette colour linearised
    assert tuple(sv.colors[0, 0]) == vertex_rgb("LS") == (3, 47, 116)  # LS blue #1f77b4 on screen ...
    assert tuple(sv.colors[T, 0]) == vertex_rgb("BCLS") == (171, 5, 5)  # ... BCLS red #d62728 (loops alternate)
    assert rgb("LS") == (0x1F, 0x77, 0xB4) and rgb("BCLS") == (0xD6, 0x27, 0x28)
    figs = build_figures(f)
    lines = {tr.name: tr.line.color for tr in figs["error"].data if tr.mode == "lines+markers"}
    assert lines == {"LS": COLORS["LS"], "BCLS": COLORS["BCLS"]}  # the same hues in the plots
    true_marker = [tr for tr in figs["eigen"].data if tr.name == "eig A (true)"][0]
    assert true_marker.marker.color == COLORS["true"] == "#000000" and rgb("true") == (0, 0, 0)


def test_reproduce_portrait_uses_the_palette():
    from app.figures import phase_portrait_figure

    f = frames(Values(bits=4, identification="BCLS", **SMALL))[0]
    fig = phase_portrait_figure(f.loops["BCLS"].states, f.true_loop.states[0], label="BCLS")
    assert [tr.line.color for tr in fig.data[:2]] == [COLORS["BCLS"], COLORS["true"]]


def test_summary_says_when_a_lessons_own_settings_were_changed():
    from app.lessons.table import lesson_values

    v = lesson_values("saturation").replace(**SMALL)
    f = frames(v)[-1]
    first = summary_markdown(f).split("\n")[0]
    assert (
        "**saturation** with changed settings (realizations, trajectories, steps, closed-loop steps)" in first
    )  # SMALL
    second = summary_markdown(frames(v.replace(u_max=1.0))[-1]).split("\n")[0]
    assert "(realizations, trajectories, steps, input bound, closed-loop steps)" in second
    third = summary_markdown(frames(lesson_values("saturation").replace(loop_seed=5, **SMALL))[-1])
    assert (
        "(realizations, trajectories, steps, closed-loop steps, loop seed)" in third
    )  # a seed its claims depend on, too
    assert "with changed" not in summary_markdown(frames(Values(**SMALL))[-1])  # no lesson open
