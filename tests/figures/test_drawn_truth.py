"""Every view of the registry draws the numbers it claims to show.

For each view :mod:`app.figures.registry` offers, built from a real small engine result of two linear plants
(dc-motor, boeing747) and a nonlinear one (van-der-pol): every trace passes :func:`drawn.check_drawn` (x and y
equally long, error bars as long as y, every band enclosing its line), and the traces' values equal the engine's
result computed on its own path (``run_sweep`` / ``run_koopman_sweep`` / the loops' states), not read back from
the figure's inputs.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from drawn import band_edges, check_drawn, line, named, values

from app.dashboard.session import iter_frames
from app.figures import registry
from app.frames.cache import SharedCache
from app.frames.datalength import datalength_config
from app.frames.render import build_figures
from app.settings.config import koopman_config
from app.settings.values import Values
from qsid_core import run_datalength, run_sweep
from qsid_core.control import CONVERGED_REL_FLOOR
from qsid_core.studies import bandwidth, run_koopman_sweep

#: More realizations than the time-series view draws one by one: its mean ± std bands are drawn (and checked).
LINEAR = dict(trajectories=10, steps=60, realizations=10, mpc_steps=20, bits=4)
NONLINEAR = dict(trajectories=20, steps=50, realizations=3, mpc_steps=30, horizon=8, bits=3)
LINEAR_PLANTS = ("dc-motor", "boeing747")
EST = {"LS": "ls", "BCLS": "bcls"}


def close(a, b, what: str) -> None:
    kind = complex if np.iscomplexobj(a) or np.iscomplexobj(b) else float
    a, b = np.asarray(a, dtype=kind), np.asarray(b, dtype=kind)
    assert a.shape == b.shape, f"{what}: {a.shape} drawn against {b.shape} computed"
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=0, equal_nan=True, err_msg=what)


@pytest.fixture(scope="module", params=LINEAR_PLANTS)
def linear(request):
    """A finished dashboard frame (every b), with a data-length study, and the engine's own sweep per estimator."""
    v = Values(system=request.param, **LINEAR)
    frame = list(iter_frames(v, SharedCache()))[-1]
    assert frame.complete
    cfg = dataclasses.replace(datalength_config(v), samples=(200, 600, 2000), realizations=3, steps_per_run=100)
    frame = dataclasses.replace(frame, datalength=run_datalength(cfg), budget=bandwidth(frame.ex.config, 2e5, "bcls"))
    sweeps = {lab: run_sweep(dataclasses.replace(frame.ex.config, estimator=e)) for lab, e in EST.items()}
    return frame, build_figures(frame), sweeps


@pytest.fixture(scope="module")
def nonlinear():
    v = Values(system="van-der-pol", lifting="poly:3", **NONLINEAR)
    frame = list(iter_frames(v))[-1]
    assert frame.complete
    frame = dataclasses.replace(frame, budget=bandwidth(frame.ex.config, 5e4, "bcls"))
    cfg, ests = koopman_config(v)
    sweeps = {lab: run_koopman_sweep(dataclasses.replace(cfg, estimator=EST[lab])) for lab in frame.labels}
    return frame, build_figures(frame), sweeps


def results(sweep) -> dict[int, dict]:
    return {r["bits"]: r for r in sweep.to_dict()["results"]}


# ----- the checker itself ---------------------------------------------------------------------


def test_the_checker_fails_the_v_shaped_band_and_a_band_off_its_line():
    """The norm plot's old band (max + min[::-1] added: 51 y for 102 x) and a band that misses its median."""
    t = [0, 1, 2]
    hi, lo, med = np.array([3.0, 2.0, 1.0]), np.array([1.0, 0.5, 0.1]), [2.0, 1.0, 0.5]
    old = [
        dict(type="scatter", x=t + t[::-1], y=(hi + lo[::-1]).tolist(), fill="toself", legendgroup="LS"),
        dict(type="scatter", x=t, y=med, mode="lines", legendgroup="LS", name="LS"),
    ]
    with pytest.raises(AssertionError, match="6 x values against 3 y values"):
        check_drawn(old, "norm_time")
    off = [dict(old[0], y=hi.tolist() + lo[::-1].tolist()), dict(old[1], y=[2.0, 1.0, 5.0])]
    with pytest.raises(AssertionError, match=r"at x = 2.0 the band \[0.1, 1\] does not enclose"):
        check_drawn(off, "norm_time")
    check_drawn([off[0], old[1]], "norm_time")  # the right band passes
    with pytest.raises(AssertionError, match="a band without its line"):
        check_drawn([off[0]], "lonely")
    bars = [dict(type="scatter", x=[1, 2], y=[0.5, 0.6], error_y=dict(type="data", array=[0.1, -0.1]))]
    with pytest.raises(AssertionError, match="a negative error_y.array"):
        check_drawn(bars, "bits")


# ----- every view, linear plants --------------------------------------------------------------


def test_every_linear_view_is_drawn_consistently(linear):
    frame, figs, _ = linear
    assert list(figs) == [v.name for v in registry.VIEWS]
    for name, fig in figs.items():
        data = check_drawn(fig, f"{frame.system.name} {name}")
        assert data, f"{name} draws nothing"


def test_error_view_draws_the_sweeps_errors_and_theorem1(linear):
    frame, figs, sweeps = linear
    data = check_drawn(figs["error"])
    for lab, sw in sweeps.items():
        rows = results(sw)
        for axis, key in (("x", "err_A"), ("x2", "err_B")):
            x, y = line(data, lab, axis)
            close(x, sorted(rows), f"{lab} {key} b")
            close(y, [rows[b][key]["mean"] for b in x], f"{lab} {key} mean")
            band = next(t for t in data if t.get("fill") and t["legendgroup"] == lab and t.get("xaxis") == axis)
            bx, hi, _ = band_edges(band)
            close(hi, [rows[b][key]["mean"] + rows[b][key]["std"] for b in bx], f"{lab} {key} mean + std")
    ls = results(sweeps["LS"])
    for axis, key in (("x", "err_A"), ("x2", "err_B")):
        for name in ("Theorem 1", "Theorem 1 (hypotheses fail)"):
            for t in named(data, name, axis):
                for b, y in zip(values(t["x"]), values(t["y"])):
                    if np.isfinite(y):
                        close(y, ls[int(b)][f"{key}_theory"], f"{name} {key} at b = {b}")


def test_cost_residual_and_bound_views_draw_the_sweeps_rows(linear):
    frame, figs, sweeps = linear
    floor = CONVERGED_REL_FLOOR * np.linalg.norm(frame.x0)
    cost, resid, bound = (check_drawn(figs[n]) for n in ("cost", "residual", "bound"))
    true_cost = sweeps["LS"].to_dict()["mpc_cost_true_model"]
    assert any(s.y0 == pytest.approx(true_cost, rel=1e-12) for s in figs["cost"].layout.shapes)
    for lab, sw in sweeps.items():
        rows = results(sw)
        x, y = line(cost, f"{lab} model")
        close(y, [rows[b]["mpc_cost"]["mean"] for b in x], f"{lab} cost")
        x, y = line(resid, f"{lab} mean")
        close(y, [rows[b]["steady_state_error"]["mean"] for b in x], f"{lab} steady-state error")
        x, y = line(bound, f"a-posteriori δ, {lab} (median; band: max)")
        close(y, [rows[b]["ultimate_bound_realized"]["median"] for b in x], f"{lab} a-posteriori δ")
        x, y = line(bound, f"{lab} ‖x_T‖ mean")
        close(y, [max(rows[b]["final_state_norm"]["mean"], floor) for b in x], f"{lab} ‖x_T‖ mean")
        assert len(x) == sum(1 for r in rows.values() if (r["final_state_norm"]["mean"] or 0) > 0)
    x, y = line(bound, "letter's δ(ε) (Theorem 1 errors)")
    ls = results(sweeps["LS"])
    close(y, [ls[b]["ultimate_bound"] for b in x], "letter's δ(ε)")


def test_bits_view_draws_the_share_that_converged_with_its_interval(linear):
    frame, figs, sweeps = linear
    data = check_drawn(figs["bits"])
    for lab, sw in sweeps.items():
        rows = results(sw)
        t = named(data, f"{lab} stabilized")[0]
        x, y = values(t["x"]), values(t["y"])
        oc = {b: rows[b]["closed_loop_outcomes"] for b in rows}
        close(y, [100 * oc[b]["converged"] / sum(oc[b].values()) for b in x], f"{lab} stabilized %")
        # the interval encloses the share drawn
        assert np.all(values(t["error_y"]["array"]) >= 0) and np.all(values(t["error_y"]["arrayminus"]) >= 0)


def test_norm_time_view_draws_the_median_and_range_of_the_loops_norms(linear):
    """The median line is np.median of the engine's ‖x_t‖ (floored at 1e-12 ‖x0‖), the band their min..max."""
    frame, figs, sweeps = linear
    data = check_drawn(figs["norm_time"])
    floor = CONVERGED_REL_FLOOR * np.linalg.norm(frame.x0)
    for lab, sw in sweeps.items():
        lp = sw.loops[frame.bits]
        ok = ~np.asarray([bool(f) for f in lp.failure])
        norms = np.maximum(np.linalg.norm(lp.states[ok], axis=-1), floor)
        t, med = line(data, f"{lab} ‖x_t‖ (median; band: min..max)")
        close(t, np.arange(norms.shape[1]), f"{lab} t")
        close(med, np.median(norms, axis=0), f"{lab} median ‖x_t‖")
        band = next(tr for tr in data if tr.get("fill") and tr["legendgroup"] == lab)
        bx, hi, lo = band_edges(band)
        assert len(values(band["x"])) == len(values(band["y"])) == 2 * norms.shape[1]
        close(bx, t, f"{lab} band t")
        close(hi, norms.max(axis=0), f"{lab} band max")
        close(lo, norms.min(axis=0), f"{lab} band min")


def test_time_series_view_draws_each_channels_mean_and_spread(linear):
    frame, figs, sweeps = linear
    data = check_drawn(figs["timeseries"])
    n, m = frame.system.n, frame.system.m
    for lab, sw in sweeps.items():
        lp = sw.loops[frame.bits]
        ok = ~np.asarray([bool(f) for f in lp.failure])
        assert ok.sum() > 8  # mean ± std bands, not one line per loop
        means = [t for t in data if t.get("name") == f"{lab} mean ± std"]
        assert len(means) == n + m
        for k, t in enumerate(means):
            Y = lp.states[ok][..., k] if k < n else lp.inputs[ok][..., k - n]
            close(values(t["y"]), Y.mean(axis=0), f"{lab} channel {k} mean")
            band = next(
                b for b in data if b.get("fill") and b["legendgroup"] == lab and b.get("yaxis") == t.get("yaxis")
            )
            close(band_edges(band)[1], Y.mean(axis=0) + Y.std(axis=0), f"{lab} channel {k} mean + std")
    true = [t for t in data if t.get("name") == "true model"]
    close(values(true[0]["y"]), sweeps["LS"].true_loop.states[0][:, 0], "true model x1")


def test_eigen_portrait_quantizer_and_datalength_views_draw_the_engines_numbers(linear):
    frame, figs, sweeps = linear
    eig = check_drawn(figs["eigen"])
    for lab, sw in sweeps.items():
        ev = np.concatenate([np.linalg.eigvals(a) for a in sw.identification[frame.bits].A_hat])
        x, y = line(eig, f"eig {lab}")
        close(np.sort_complex(x + 1j * y), np.sort_complex(ev), f"eig {lab}")
    x, y = line(eig, "eig A (true)")
    close(np.sort_complex(x + 1j * y), np.sort_complex(np.linalg.eigvals(frame.system.A)), "eig A")
    port = check_drawn(figs["portraits"])
    ls_b2 = [t for t in port if t.get("name") == "LS" and (t.get("xaxis") or "x") == "x"][0]
    st = sweeps["LS"].loops[2].states
    i, j = 0, 1
    close(values(ls_b2["x"])[np.isfinite(values(ls_b2["x"]))], st[..., i].reshape(-1), "portrait b = 2 x")
    close(values(ls_b2["y"])[np.isfinite(values(ls_b2["y"]))], st[..., j].reshape(-1), "portrait b = 2 y")
    q = check_drawn(figs["quantizer"])
    eps = sweeps["LS"].identification[frame.bits].eps[int(frame.values.view_channel)]
    x, y = line(q, "uniform 1/ε on ±ε/2")
    close(x, [-eps / 2, -eps / 2, eps / 2, eps / 2], "the uniform law's support")
    close(y[1], 1 / eps, "the uniform density")
    for name in ("error, dithered", "error, no dither"):
        h = named(q, name)[0]
        width = h["width"]
        assert float(np.nansum(values(h["y"]))) * width == pytest.approx(1.0, rel=1e-9)  # a density
    dl = check_drawn(figs["datalength"])
    for lab in ("LS", "BCLS"):
        x, y = line(dl, f"{lab} mean ± std", "x")
        rows = frame.datalength.to_dict()["rows"]
        close(x, [r["samples"] for r in rows], f"{lab} samples")
        close(y, [r[lab.lower()]["err_A"]["mean"] for r in rows], f"{lab} data-length err_A")


def test_bandwidth_view_draws_the_budget_study(linear):
    frame, figs, _ = linear
    data = check_drawn(figs["bandwidth"])
    rows = [r for r in frame.budget.noise_free.to_dict()["rows"] if r["identifiable"]]
    x, y = line(data, f"noise-free: err_G (knee b = {frame.budget.noise_free.b_knee})", "x")
    close(x, [r["bits"] for r in rows], "bandwidth b")
    close(y, [r["err_G"]["mean"] for r in rows], "bandwidth err_G")
    x, y = line(data, f"noise-free: predicted (knee b = {frame.budget.noise_free.b_knee_predicted})", "x")
    close(y, [r["predicted_err_G"] for r in rows], "bandwidth predicted err_G")


# ----- every view, a nonlinear plant ----------------------------------------------------------


def test_every_nonlinear_view_draws_the_koopman_sweep(nonlinear):
    frame, figs, sweeps = nonlinear
    assert list(figs) == [v.name for v in registry.KOOPMAN_VIEWS]
    data = {name: check_drawn(fig, f"van-der-pol {name}") for name, fig in figs.items()}
    assert all(data.values())
    for lab, sw in sweeps.items():
        rows = {r["bits"]: r for r in sw.rows}
        x, y = line(data["koopman-error"], f"{lab}: quantized EDMD")
        close(y, [rows[b]["err_G"]["mean"] for b in x], f"{lab} err_G")
        x, y = line(data["koopman-prediction"], lab)
        close(y, [rows[b]["prediction_error"]["mean"] for b in x], f"{lab} prediction error")
        left = [t for t in data["koopman-outcomes"] if t.get("hovertemplate", "").startswith(f"{lab} ")]

        def loops(r: dict, kind: str) -> int:
            """The row's loops of one bar segment: the bounded ones split by ending within the radius (a
            converged loop ends within it too)."""
            oc = r["closed_loop_outcomes"]
            near = max(0, min(oc["bounded"], (r.get("within_radius") or 0) - oc["converged"]))
            return {"bounded, within radius": near, "bounded": oc["bounded"] - near}.get(kind, oc.get(kind, -1))

        for t in left:
            kind = t["name"]
            xs = values(t["x"])
            close(
                values(t["y"]),
                [loops(rows[round(b)], kind) / rows[round(b)]["realizations"] for b in xs],
                f"{lab} {kind} share",
            )
        ev = np.concatenate([np.linalg.eigvals(mdl.A) for mdl in frame.models[lab].models])
        x, y = line(data["koopman-eigen"], f"eig {lab}")
        close(np.sort_complex(x + 1j * y), np.sort_complex(ev), f"eig A_z {lab}")
    ls = {r["bits"]: r for r in sweeps["LS"].rows}
    limit = named(data["koopman-error"], "LS large-data limit")
    if limit:
        x, y = values(limit[0]["x"]), values(limit[0]["y"])
        close(y, [ls[int(b)]["large_data"]["err_G"] for b in x], "LS large-data limit")
    floor = sweeps["LS"].reference_prediction_error
    assert any(s.y0 == pytest.approx(floor, rel=1e-12) for s in figs["koopman-prediction"].layout.shapes)


# ----- the figures outside the panel: CLI --figure, a pinned result, the reproduce portraits -------


def test_cli_figures_pinned_overlays_and_portraits_draw_consistent_data(linear):
    """``plot_results`` (``qsid sweep --figure``) of both estimators' sweeps, a pinned earlier frame dashed over
    the curves, and the 3-D phase portrait of ``qsid reproduce``: the same checks; the plotted errors equal
    the sweeps' rows."""
    import dataclasses as dc

    from app.figures import phase_portrait_figure, plot_results
    from app.figures.results import VIEWS

    frame, _, sweeps = linear
    for view in VIEWS:
        data = check_drawn(plot_results(*sweeps.values(), view=view, labels=list(sweeps)), f"plot_results {view}")
        if view == "error":
            for lab, sw in sweeps.items():
                rows = results(sw)
                x, y = line(data, lab, "x")
                close(y, [rows[b]["err_A"]["mean"] for b in x], f"plot_results {lab} err_A")
    pinned = build_figures(dc.replace(frame, pinned=dc.replace(frame, bits=2)), ["error", "cost", "bound"])
    for name, fig in pinned.items():
        data = check_drawn(fig, f"pinned {name}")
        assert any("(pinned b=2)" in (t.get("name") or "") for t in data), name
    st = sweeps["LS"].loops[frame.bits].states
    fig = phase_portrait_figure(st, sweeps["LS"].true_loop.states[0], dims=(0, 1, None))
    assert any(t.get("type") == "scatter3d" for t in check_drawn(fig, "phase portrait"))
