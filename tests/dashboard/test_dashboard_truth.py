"""Issue 7 in the dashboard's views: assumption marks, the two bounds, axes that cannot blow up."""

from __future__ import annotations

import numpy as np
import pytest

from app.dashboard.session import iter_frames
from app.figures.axes import MAX_DECADES, axis_ranges, finite_axes
from app.figures.bound import CAPTION
from app.frames.cache import SharedCache
from app.frames.render import build_figures
from app.frames.summary import summary_markdown
from app.settings.config import sweep_config
from app.settings.values import InputError, Values

SMALL = dict(trajectories=10, steps=60, realizations=4, mpc_steps=15)
CACHE = SharedCache()


def last(v: Values):
    return list(iter_frames(v, CACHE))[-1]


def check_axes(figs: dict) -> None:
    """Every 2-D axis with data has an explicit finite range; log axes span at most 12 decades."""
    for name, fig in figs.items():
        rng = axis_ranges(fig)
        assert rng or name not in ("error", "cost", "bound", "norm_time", "eigen", "timeseries"), name
        for key, (kind, r) in rng.items():
            assert r is not None and np.all(np.isfinite(r)) and r[1] > r[0], (name, key, r)
            if kind == "log":
                assert r[1] - r[0] <= MAX_DECADES + 1e-9, (name, key, r)


def test_issue_repro_boeing_mpc_axes_are_finite_and_at_most_12_decades():
    """Boeing, Q u = 10^2, Q w = 10, R elevator = 0.1, horizon 30, input bound 0.2 (issue 7, defect 5)."""
    v = Values(
        system="boeing747",
        log_q=(2, 1, -1, -1),
        log_r=(-1, 0),
        horizon=30,
        u_max=0.2,
        trajectories=10,
        steps=60,
        realizations=3,
        mpc_steps=30,
    )
    f = last(v)
    figs = build_figures(f)
    check_axes(figs)
    # the converged final norms are drawn at the floor, never at 1e-48
    lo = axis_ranges(figs["bound"])["yaxis"][1][0]
    assert lo > np.log10(1e-12 * np.linalg.norm(f.x0)) - 1


@pytest.mark.parametrize("seed", range(6))
def test_random_settings_give_finite_axes(seed):
    rng = np.random.default_rng(seed)
    v = Values(
        system=str(rng.choice(["dc-motor", "boeing747"])),
        bits=int(rng.integers(1, 17)),
        dither=str(rng.choice(["subtractive", "none"])),
        guard=bool(rng.integers(2)),
        range_mode=str(rng.choice(["per-channel", "shared", "fixed"])),
        fixed_range="-20, 20",
        horizon=int(rng.integers(1, 31)),
        u_max=float(rng.choice([0.05, 0.2, 1.0, 10.0])),
        input_amplitude=float(rng.choice([0.01, 1.0, 5.0])),
        theta=float(rng.choice([0.1, 0.5, 0.9])),
        trajectories=5,
        steps=40,
        realizations=2,
        mpc_steps=20,
    )
    check_axes(build_figures(last(v)))


def test_a_huge_log_span_is_cut_to_12_decades_and_narrow_spans_get_sparse_ticks():
    import plotly.graph_objects as go

    fig = go.Figure(go.Scatter(x=[1, 2, 3, 4], y=[1e-21, 3.0, 5.0, 1e289]))
    fig.update_yaxes(type="log", title_text="cost")
    finite_axes(fig)
    r = fig.layout.yaxis.range
    assert r[1] - r[0] <= 12 and r[0] <= np.log10(3.0) and r[1] >= np.log10(5.0)
    assert "off the axis" in fig.layout.yaxis.title.text
    fig = go.Figure(go.Scatter(x=[1, 2], y=[1.2, 9.0]))
    fig.update_yaxes(type="log")
    finite_axes(fig)
    # 1, 2, 5 per decade (no "10 9 8 .. 2 1"), each labelled in full
    assert list(fig.layout.yaxis.ticktext) == ["1", "2", "5", "10"]
    fig = go.Figure(go.Scatter(x=[1, 2], y=[0.15, 0.6]))
    fig.update_yaxes(type="log")
    finite_axes(fig)
    assert list(fig.layout.yaxis.ticktext) == ["0.1", "0.2", "0.5", "1"]  # 0.5, not plotly's bare "5"


def test_finite_axes_reads_every_trace_and_data_shape_and_keeps_set_ranges():
    import plotly.graph_objects as go

    fig = go.Figure()
    fig.add_trace(go.Scatter(x=[0, 1], y=[1.0, 2.0]))
    fig.add_trace(go.Scatter(x=[0, 1], y=[np.nan, 100.0], xaxis="x2", yaxis="y2"))  # a second pair of axes
    fig.add_trace(go.Scatter(x=[0, 1], y=[0, 1], xaxis="x3", yaxis="y3"))  # axes the layout lacks: left alone
    fig.add_trace(go.Scatter3d(x=[0, 1e9], y=[0, 1e9], z=[0, 1]))  # no 2-D axis: ignored
    fig.add_shape(type="line", x0=0, x1=1, y0=5.0, y1=5.0, yref="y")  # a line in data units counts
    fig.add_shape(type="line", x0=0, x1=1, y0=0, y1=1e6, xref="paper", yref="y domain")  # in paper units: not
    fig.update_layout(xaxis=dict(range=[-3, 3]), xaxis2=dict(anchor="y2"), yaxis2=dict(anchor="x2"))  # x: kept
    finite_axes(fig)
    assert list(fig.layout.xaxis.range) == [-3, 3]
    lo, hi = fig.layout.yaxis.range
    assert lo < 1.0 and 5.0 < hi < 6.0 and fig.layout.yaxis.autorange is False
    lo2, hi2 = fig.layout.yaxis2.range
    assert lo2 < 100.0 < hi2 < 200.0 and fig.layout.xaxis2.range is not None
    assert "xaxis3" not in fig.layout and "yaxis3" not in fig.layout


def test_dc_motor_integrator_fades_theorem1_and_says_why():
    f = last(Values(**SMALL))
    fig = build_figures(f, ["error"])["error"]
    names = [t.name for t in fig.data]
    faded = [t for t in fig.data if t.name == "Theorem 1 (hypotheses fail)"]
    assert faded and all(t.opacity < 0.5 and t.line.dash == "dot" for t in faded)
    assert "Theorem 1" not in names  # no b where the hypotheses hold: no normal line at all
    note = [a.text for a in fig.layout.annotations if a.hovertext]
    assert note == ["Notes: Theorem 1 faded (hover here: why)"]  # one line on the plot ...
    why = " ".join(a.hovertext or "" for a in fig.layout.annotations)
    assert "unit circle (integrator)" in why
    assert "does not converge" in why  # ... the whole sentence on hover (and in the summary)
    assert "unit circle (integrator): Ψ Ψᵀ/T does not converge" in summary_markdown(f)


def test_the_letters_slopes_are_printed_for_its_dc_motor_only():
    motor = build_figures(last(Values(**SMALL)), ["error"])["error"]
    boeing = build_figures(last(Values(system="boeing747", **SMALL)), ["error"])["error"]
    assert "(letter −0.322)" in " ".join(a.text for a in motor.layout.annotations)
    titles = " ".join(a.text for a in boeing.layout.annotations)
    assert "slope −" in titles and "letter" not in titles


def test_boeing_with_guard_band_draws_theorem1_normally_where_it_holds():
    f = last(Values(system="boeing747", trajectories=200, steps=300, realizations=2, mpc_steps=10))
    holds = {b for b, r in f.rows["LS"].items() if r["assumptions"]["theorem1_holds"]}
    assert holds and holds != set(f.rows["LS"])  # holds at coarse b, not in the finite-data regime
    fig = build_figures(f, ["error"])["error"]
    normal = [t for t in fig.data if t.name == "Theorem 1"][0]  # the A panel's line
    drawn = {b for b, y in zip(normal.x, normal.y) if y is not None}
    a = {b: r["assumptions"] for b, r in f.rows["LS"].items()}
    # drawn for A where every hypothesis holds for A, or one formally fails yet LS is within 5 % of the line
    assert drawn == {b for b in a if a[b]["theorem1_holds_A"] or a[b]["fits_A"]} and normal.line.dash == "dash"
    assert holds <= drawn
    for b in drawn - holds:
        ls = f.rows["LS"][b]["err_A"]["mean"]
        assert a[b]["theorem1_holds_A"] or abs(ls - a[b]["bias_A"]) <= 0.05 * a[b]["bias_A"], b


def test_bcls_without_dither_is_marked():
    f = last(Values(system="boeing747", dither="none", **SMALL))
    fig = build_figures(f, ["error"])["error"]
    marks = [t for t in fig.data if t.name == "BCLS: noise not ε²/12"]
    assert marks and len(marks[0].x) == len(f.rows["BCLS"])
    s = summary_markdown(f)
    assert "its hypotheses fail" in s and "4 dither realizations (1 distinct" in s


def test_bound_plot_shows_both_bounds_with_the_caption():
    f = last(Values(**SMALL))
    fig = build_figures(f, ["bound"])["bound"]
    names = [t.name for t in fig.data]
    assert "letter's δ(ε) (Theorem 1 errors)" in names
    med = [t for t in fig.data if (t.name or "").startswith("a-posteriori δ, LS")][0]
    assert len(med.x) == 16
    assert med.y[3] == pytest.approx(f.rows["LS"][4]["ultimate_bound_realized"]["median"])
    assert fig.layout.annotations[0].text.startswith(CAPTION)
    assert f"T = {f.values.mpc_steps} steps" in fig.layout.annotations[0].text  # ‖x_T‖ is at a finite T
    ls_d, bcls_d = (
        next(t for t in fig.data if (t.name or "").startswith(f"a-posteriori δ, {k}")) for k in ("LS", "BCLS")
    )
    assert ls_d.line.color == bcls_d.line.color and bcls_d.line.dash == "dot"  # the bound's colour, not BCLS red
    s = summary_markdown(f)
    assert f"ρ = {f.rows['LS'][4]['rho']:.3g} (automatic)" in s and "a-posteriori δ LS" in s


def test_input_amplitude_reaches_the_engine_and_bad_values_are_explained():
    v = Values(input_amplitude=0.25)
    assert sweep_config(v, __import__("qsid_core").get_system("dc-motor")).input_amplitude == 0.25
    with pytest.raises(InputError, match="input amplitude must be a positive number"):
        sweep_config(Values(input_amplitude=0.0), __import__("qsid_core").get_system("dc-motor"))


def test_guard_band_is_on_by_default():
    from qsid_core.quantization.quantize import QuantizerSpec

    assert Values().guard is True and QuantizerSpec().guard is True


# ----- 3-D view: outlines, off-scale label, toggle, time axis, time markers -------------------


def test_bounds_are_outlines_to_scale_or_an_off_scale_label_and_can_be_hidden():
    from app.figures.phase_scene import SPHERE_CAP, scene_view

    f = last(Values(system="boeing747", bits=12, **SMALL))
    sv = scene_view(f)
    assert 0 < sv.sphere_radius <= SPHERE_CAP and sv.bound_circles.shape[0] == 3 * 48  # 3 planes x 48 segments
    r = np.linalg.norm(sv.bound_circles.reshape(-1, 3), axis=1)
    np.testing.assert_allclose(r, sv.delta / sv.scale, rtol=1e-5)  # to scale, around x_ref = 0
    big = scene_view(last(Values(bits=2, **SMALL)))
    assert big.sphere_capped and big.bound_circles.shape[0] == 0 and "off scale" in big.bound_text
    hidden = scene_view(last(Values(system="boeing747", bits=12, show_bound=False, **SMALL)))
    assert hidden.bound_circles.shape[0] == 0 and hidden.realized_circles.shape[0] == 0


def test_small_systems_draw_time_on_the_free_axis_with_time_markers():
    from app.figures.phase_scene import TIME, scene_view

    v = Values(system="custom", a_text="0.9 0.1\n0 0.8", b_text="0\n1", dither="none", **SMALL)
    f = last(v)
    sv = scene_view(f)
    assert sv.axis_names == ("x1", "x2", "time")
    z = sv.true_segments[:, :, 2]
    assert z.min() == 0 and z.max() == pytest.approx(TIME) and np.all(np.diff(z[:, 0]) > 0)
    assert sv.time_marks.shape[0] >= 5 and sv.mark_every >= 1
    assert sv.polylines == 2 and sv.realizations == 8  # no dither: 4 identical loops per estimator


def test_norm_time_view_shows_both_bounds_and_never_below_the_floor():
    f = last(Values(system="boeing747", bits=10, mpc_steps=60, trajectories=10, steps=60, realizations=4))
    fig = build_figures(f, ["norm_time"])["norm_time"]
    ys = [s.y0 for s in fig.layout.shapes]
    r = f.rows["LS"][10]
    assert r["ultimate_bound"] in ys and r["ultimate_bound_realized"]["median"] in ys
    floor = 1e-12 * np.linalg.norm(f.x0)
    assert min(min(y for y in t.y if y is not None) for t in fig.data) >= floor * (1 - 1e-12)
    assert CAPTION in fig.layout.title.text
    check_axes({"norm_time": fig})
    lo, hi = fig.layout.yaxis.range  # both bounds and the start of the loops are on the axis
    for y in (r["ultimate_bound"], r["ultimate_bound_realized"]["median"], np.linalg.norm(f.x0)):
        assert lo <= np.log10(y) <= hi, (y, lo, hi)


def test_norm_time_keeps_the_bounds_on_the_axis_when_loops_converge_far_below():
    """dc-motor at b = 4 (the default): bounds ~10-100 above ||x0||, loops converge to 1e-12 ||x0||."""
    f = last(Values(bits=4, mpc_steps=50, **{k: v for k, v in SMALL.items() if k != "mpc_steps"}))
    fig = build_figures(f, ["norm_time"])["norm_time"]
    lo, hi = fig.layout.yaxis.range
    r = f.rows["LS"][4]
    for y in (r["ultimate_bound"], r["ultimate_bound_realized"]["median"]):
        assert lo <= np.log10(y) <= hi, (y, lo, hi)
    assert hi - lo <= MAX_DECADES + 1e-9


def test_bound_view_keeps_the_bounds_on_the_axis_and_shows_converged_norms_on_its_edge():
    """dc-motor default: bounds 1e-6..1e4 over b, final norms converged to 1e-12 ||x0|| (16 decades in all)."""
    f = last(Values(bits=4, mpc_steps=50, **{k: v for k, v in SMALL.items() if k != "mpc_steps"}))
    fig = build_figures(f, ["bound"])["bound"]
    lo, hi = fig.layout.yaxis.range
    assert hi - lo <= MAX_DECADES + 1e-9
    for b, r in f.rows["LS"].items():
        for y in (r["ultimate_bound"], r["ultimate_bound_realized"]["median"]):
            assert y is None or not np.isfinite(y) or y <= 0 or lo <= np.log10(y) <= hi, (b, y, lo, hi)
    below = [t for t in fig.data if (t.name or "").startswith("‖x_T‖ below the axis")]
    finals = [r["final_state_norm"]["mean"] for r in f.rows["LS"].values()]
    n_below = sum(1 for y in finals if y is not None and 0 < y < 10**lo)
    assert n_below > 0  # the converged loops of this setting
    mean_below = [t for t in below if t.meta == "LS ‖x_T‖ mean"]
    assert sum(bool(t.showlegend) for t in below) == 1  # one legend entry for the edge
    assert len(mean_below) == 1 and len(mean_below[0].x) == n_below
    assert all(lo <= np.log10(y) <= hi for y in mean_below[0].y)


def test_time_markers_do_not_pile_up_where_the_loop_has_converged():
    """dc-motor default (3 states, no time axis): the loop converges within ~10 of 50 steps; markers every
    5 steps used to stack on the origin. Kept markers are at least MARK_GAP apart, and the first is x0."""
    from app.figures.phase_scene import MARK_GAP, scene_view

    f = last(Values(mpc_steps=50, **{k: v for k, v in SMALL.items() if k != "mpc_steps"}))
    sv = scene_view(f)
    m = sv.time_marks
    assert 1 <= m.shape[0] < 50 // sv.mark_every + 1  # some were dropped
    assert np.allclose(m[0], sv.start, atol=1e-6)
    d = np.linalg.norm(np.diff(m, axis=0), axis=1)
    assert np.all(d >= MARK_GAP - 1e-6)
    assert all(len(line) <= 60 for line in sv.bound_text.split("\n"))  # one fact per line: fits the canvas


def test_norm_time_without_converged_loops_has_no_floor_line_and_no_false_title():
    """Boeing at b = 2 over 15 steps: the loops are far from converged; the axis follows the data."""
    f = last(Values(system="boeing747", bits=2, **SMALL))
    fig = build_figures(f, ["norm_time"])["norm_time"]
    ys = [y for t in fig.data for y in t.y if y is not None and y > 0]
    floor = 1e-12 * np.linalg.norm(f.x0)
    assert min(ys) > 10 * floor  # nothing converged in this setting
    assert not any("converged" in (a.text or "") for a in fig.layout.annotations)
    assert "below the axis" not in fig.layout.yaxis.title.text
    lo, hi = fig.layout.yaxis.range
    assert lo > np.log10(floor) + 3  # the axis is not stretched down to the floor
    xs = [a.x for a in fig.layout.annotations]
    assert len(set(xs)) == len(xs)  # bound labels at different places (they printed on each other)


def test_quantizer_view_counts_errors_off_the_histogram_under_overload():
    """Walkthrough repro: fixed range -1, 1 (most samples overloaded) showed a uniform-looking histogram and
    a variance ratio of ~5e6 '(± 0.009)'."""
    f = last(Values(range_mode="fixed", fixed_range="-1, 1", **SMALL))
    title = build_figures(f, ["quantizer"])["quantizer"].layout.title.text
    assert "errors outside ±ε/2" in title and "(±" not in title
    ok = build_figures(last(Values(**SMALL)), ["quantizer"])["quantizer"].layout.title.text
    assert "(±" in ok and "outside" not in ok  # no overload with the guard band: the ideal law and its spread


def test_time_series_title_counts_failed_loops():
    """Walkthrough repro: with x_max = 0.5 every LS loop was infeasible, yet the title said 'LS 0 steps in 0/5
    loops' and LS silently left the legend."""
    f = last(Values(system="boeing747", x0="5, 5, 0, 0", x_max="0.5", **SMALL))
    failed = {lab: int(f.loops[lab].failed.sum()) for lab in f.labels}
    assert any(failed.values()), failed  # the setting does make loops fail
    title = build_figures(f, ["timeseries"])["timeseries"].layout.title.text
    for lab, k in failed.items():
        if k:
            assert f"{lab} {k}/{len(f.loops[lab].failure)} failed (" in title and "not drawn" in title
