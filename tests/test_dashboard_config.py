"""Dashboard pure pieces: panel values -> engine config, plain-words errors, shared cache, frames, figures."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from app.dashboard_compute import (
    CLIP, SPHERE_CAP, Renderer, build_figures, iter_frames, scene_view, summary_markdown,
)
from app.dashboard_state import (
    ALL_BITS, INTERACTIVE, PAPER_SCALE, InputError, SharedCache, Values, axes_indices, axes_options,
    estimators, format_weights, log_from_weights, matrix_text, mpc_config, resolve_system, sweep_config,
    weights_from_log,
)
from app.figures import move_current_bits
from qsid_core import Experiment
from qsid_core.errors import QsidError

SMALL = dict(trajectories=10, steps=60, realizations=4, mpc_steps=15)


def frames(v: Values, cache=None):
    return list(iter_frames(v, cache if cache is not None else SharedCache()))


# ----- values -> config --------------------------------------------------------------------

def test_defaults_map_to_the_interactive_sweep():
    v = Values()
    sysm = resolve_system(v).system
    cfg = sweep_config(v, sysm)
    assert cfg.bits == ALL_BITS == tuple(range(1, 17))
    assert (cfg.trajectories, cfg.steps, cfg.realizations) == (50, 200, 20)
    assert INTERACTIVE == {"trajectories": 50, "steps": 200, "realizations": 20}
    assert PAPER_SCALE == {"trajectories": 200, "steps": 1000, "realizations": 50}
    assert cfg.estimator == "ls" and cfg.theta == 0.5 and cfg.rho is None
    assert cfg.quantizer.dither == "subtractive" and cfg.quantizer.range_mode == "per-channel"
    assert cfg.mpc.horizon == 10 and cfg.mpc.steps == 50 and cfg.mpc.u_max == (1.0,)
    assert cfg.mpc.Q is None and cfg.mpc.R is None and cfg.mpc.x0 is None  # the system's defaults


def test_every_control_reaches_the_config():
    v = Values(system="boeing747", bits=7, dither="none", range_mode="shared", guard=True, realizations=3,
               dither_seed=9, trajectories=12, steps=40, data_seed=5, identification="BCLS", horizon=7,
               log_q=(0.0, -1.0, 1.0, 0.5), log_r=(0.3, -0.3), u_max=2.5, x0="1, 0.5, 0, 0", mpc_steps=30,
               theta=0.3, rho_auto=False, rho=2.0)
    sysm = resolve_system(v).system
    cfg = sweep_config(v, sysm)
    assert sysm.name == "boeing747"
    assert (cfg.realizations, cfg.dither_seed, cfg.trajectories, cfg.steps, cfg.data_seed) == (3, 9, 12, 40, 5)
    assert cfg.quantizer.dither == "none" and cfg.quantizer.range_mode == "shared" and cfg.quantizer.guard
    assert cfg.estimator == "bcls" and cfg.theta == 0.3 and cfg.rho == 2.0
    m = cfg.mpc
    assert (m.horizon, m.steps, m.u_max, m.x0) == (7, 30, (2.5,), (1.0, 0.5, 0.0, 0.0))
    assert m.Q == (1.0, 0.1, 10.0, 3.162) and m.R == (1.995, 0.5012)


def test_log_sliders_hold_log10_of_the_weight():
    assert weights_from_log([0, -1, 1, 0.5]) == (1.0, 0.1, 10.0, 3.162)
    assert log_from_weights([1.0, 0.1, 100.0]) == (0.0, -1.0, 2.0)
    assert log_from_weights([0.0, 1e9]) == (-3.0, 3.0)  # zero and huge weights land at the slider ends
    for w in (0.01, 0.5, 1.0, 7.0):
        assert weights_from_log(log_from_weights([w]))[0] == pytest.approx(w, rel=0.02)
    assert format_weights("Q", (1.0, 0.1)) == "Q = diag(1, 0.1)"
    sysm = resolve_system(Values()).system
    assert mpc_config(Values(log_q=(0.0, 0.0, 0.0)), sysm).Q == (1.0, 1.0, 1.0)
    assert mpc_config(Values(log_q=(0.0, 0.0)), sysm).Q is None  # wrong length (another system's): default


def test_estimator_choices():
    assert estimators("LS") == ("ls",) and estimators("BCLS") == ("bcls",)
    assert estimators("LS + BCLS") == ("ls", "bcls")
    with pytest.raises(InputError, match="identification must be one of"):
        estimators("ML")


def test_custom_system_from_typed_matrices():
    v = Values(system="custom", a_text="0.9 0.2\n0 0.8", b_text="0; 1")
    ch = resolve_system(v)
    assert ch.system.n == 2 and ch.system.m == 1 and ch.notes == ()
    np.testing.assert_allclose(ch.system.A, [[0.9, 0.2], [0.0, 0.8]])
    cfg = sweep_config(v, ch.system)
    assert cfg.mpc.Q is None
    assert axes_indices("", ch.system.state_names) == (0, 1, None)
    # the boxes show a preset the same way they are typed
    assert matrix_text(np.array([[1.0, 0.099], [0.0, -2.5]])) == "1 0.099\n0 -2.5"


@pytest.mark.parametrize("a, b, words", [
    ("1 2\n3 x", "1; 0", "A row 2: '3 x' has an entry that is not a number"),
    ("1 2\n3", "1; 0", "A: rows have different lengths"),
    ("", "1", "A is empty"),
    ("1 2 3\n4 5 6", "1; 0", "A must be square"),
    ("0.9 0.2\n0 0.8", "1; 0; 2", "B must have one row per state (2 rows, like A); it has 3"),
    ("0.9 0.2\n0 0.8", "1 0", "did you type B transposed?"),
    ("0.9 0.2\n0 0.8", "[[1], [0]", "B: not valid JSON"),
    ("0.9 inf\n0 0.8", "1; 0", "only finite numbers"),
])
def test_bad_custom_matrices_say_what_is_wrong(a, b, words):
    with pytest.raises(InputError) as exc:
        resolve_system(Values(system="custom", a_text=a, b_text=b))
    msg = str(exc.value)
    assert msg.startswith("Custom system: ")
    assert words in msg
    assert isinstance(exc.value, QsidError) and isinstance(exc.value, ValueError)


def test_uncontrollable_custom_system_gives_a_note_not_an_error():
    ch = resolve_system(Values(system="custom", a_text="0.5 0\n0 0.5", b_text="1; 0"))
    assert len(ch.notes) == 1 and "not controllable" in ch.notes[0] and "MPC may fail" in ch.notes[0]


@pytest.mark.parametrize("field, value, words", [
    ("x0", "1, 2", "x0 needs 3 numbers (one per state: angle, speed, current); got 2"),
    ("x0", "1, a, 0", "not a number"),
    ("fixed_range", "2, 1", "every range needs lo < hi"),
    ("fixed_range", "1 2 3", "fixed range: give one 'lo, hi' pair"),
    ("u_max", -1.0, "u_max must be positive"),
    ("bits", 17, "word length b must be between 1 and 16"),
    ("rho", -2.0, "rho must be a positive number"),
    ("theta", 1.0, "theta must be in (0, 1)"),
])
def test_bad_panel_values_raise_plain_words(field, value, words):
    kw = {field: value}
    if field == "fixed_range":
        kw["range_mode"] = "fixed"
    if field == "rho":
        kw["rho_auto"] = False
    v = Values(**kw)
    with pytest.raises(InputError) as exc:
        sweep_config(v, resolve_system(v).system)
    assert words in str(exc.value)


def test_fixed_range_one_pair_or_one_per_channel():
    v = Values(range_mode="fixed", fixed_range="-30, 30")
    sysm = resolve_system(v).system
    assert sweep_config(v, sysm).quantizer.fixed_range == ((-30.0, 30.0),)
    v = v.replace(fixed_range="-30 30; -5 5; -1 1; -1 1; -1 1")
    assert len(sweep_config(v, sysm).quantizer.fixed_range) == 5


def test_axes_choices_for_four_states():
    names = ("u", "w", "q", "theta")
    opts = axes_options(names)
    assert opts == ["u, w, q", "u, w, theta", "u, q, theta", "w, q, theta"]
    assert axes_indices("u, q, theta", names) == (0, 2, 3)
    assert axes_indices("nonsense", names) == (0, 1, 2)
    assert axes_options(("a", "b", "c")) == ["a, b, c"]


# ----- shared cache -----------------------------------------------------------------------

def test_shared_cache_is_a_bounded_lru():
    c = SharedCache(max_bytes=3 * 8000 + 500, keep=1)
    for i in range(5):
        c[("x", i)] = np.zeros(1000)
    assert len(c) == 3 and ("x", 0) not in c and ("x", 4) in c
    _ = c[("x", 2)]  # touch: now the most recent
    c[("x", 5)] = np.zeros(1000)
    assert ("x", 2) in c and ("x", 3) not in c
    assert c.kinds() == {"x": 3}
    with pytest.raises(KeyError):
        c[("missing",)]


def test_shared_cache_survives_threads():
    c = SharedCache(max_bytes=50 * 800, keep=4)

    def work(t):
        for i in range(300):
            c[(t, i)] = np.zeros(100)
            _ = (t, i) in c
            list(c)

    ths = [threading.Thread(target=work, args=(t,)) for t in range(4)]
    for t in ths:
        t.start()
    for t in ths:
        t.join()
    assert len(c) <= 50 and c.nbytes <= 50 * 800 + 4 * 1000


def test_engine_cache_keys_separate_what_a_change_touches():
    """b change: no new data; Q/R change: no new identification (the dashboard relies on it)."""
    cache = SharedCache()
    v = Values(**SMALL)
    frames(v, cache)
    before = cache.kinds()
    assert before["data"] == 1 and before["mom"] == 16 and before["ident"] == 32
    frames(v.replace(bits=9), cache)
    assert cache.kinds() == before  # everything was cached
    frames(v.replace(log_q=(0.5, -1.0, -1.0), log_r=(0.0, 0.2)), cache)
    after = cache.kinds()
    assert after["data"] == 1 and after["mom"] == 16 and after["ident"] == 32  # no new identification
    assert after["loops"] == 2 * before["loops"]  # new closed loops only
    frames(v.replace(data_seed=3), cache)
    assert cache.kinds()["data"] == 2


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
    assert sv.sphere_radius == pytest.approx(min(f.theory.delta / sv.scale, SPHERE_CAP))
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
    assert set(figs) == {"error", "cost", "bound", "eigen"}
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
    assert len(eig.data[1].x) == 4 * 3  # 4 realizations x 3 eigenvalues (LS)


def test_renderer_redraws_only_what_changed():
    cache = SharedCache()
    ren = Renderer()
    v = Values(**SMALL)
    out = [ren.render(f) for f in iter_frames(v, cache)]
    assert out[0].scene is not None and out[0].summary and "eigen" in out[0].figures
    assert set(out[-1].figures) == {"error", "cost", "bound"}
    err = ren.figures["error"]
    # a b change: new scene and eigenvalues, the curves are only re-marked (same figure objects)
    out = [ren.render(f) for f in iter_frames(v.replace(bits=8), cache)]
    assert out[0].scene is not None and "eigen" in out[0].figures
    assert out[-1].figures["error"] is err and [s.x0 for s in err.layout.shapes] == [8, 8]
    # a Q change: same models, no new eigenvalue plot, new curves
    out = [ren.render(f) for f in iter_frames(v.replace(bits=8, log_q=(1.0, -1.0, -1.0)), cache)]
    assert "eigen" not in out[0].figures
    assert out[-1].figures["cost"] is not None and ren.figures["error"] is not err


def test_summary_lists_eps_errors_overload_and_failures():
    f = frames(Values(bits=2, **SMALL))[-1]
    text = summary_markdown(f)
    assert "b = **2** bits" in text and "ε states: angle" in text and "ε inputs: voltage" in text
    assert "overload:" in text and "| LS |" in text and "| BCLS |" in text and "Thm 1" in text
    assert "MPC cost with the true model" in text
    lp = f.loops["LS"]
    lp.failure[0], lp.messages[0] = "dare", "DARE has no stabilizing solution for the identified model"
    f.rows["LS"][2]["mpc_cost"]["failed"] = 1
    f.rows["LS"][2]["mpc_cost"]["failures"] = {"dare": 1}
    text = summary_markdown(f)
    assert "1/4 (1 dare)" in text and "LS MPC: DARE has no stabilizing solution" in text


def test_a_failed_identification_is_reported_and_not_drawn():
    f = frames(Values(bits=3, **SMALL))[-1]
    ident = f.idents["LS"]
    ident.A_hat[1] = np.nan
    ident.failed = np.array([False, True, False, False])
    ident.notes = ["identification failed: singular data"]
    f.rows["LS"][3] = {**f.rows["LS"][3], "ident_failures": 1}
    eig = build_figures(f, ("eigen",))["eigen"]
    assert len(eig.data[1].x) == 3 * 3  # 3 good realizations x 3 eigenvalues
    assert "LS identification failed in 1 of 4 realizations" in summary_markdown(f)
