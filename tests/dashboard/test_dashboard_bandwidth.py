"""The bit budget in the dashboard: a setting (panel, settings file), the tab's study ending with its budget study,
the bandwidth view (with and without a result) and "as a command": the ``qsid budget`` line gives the very rows
the view draws."""

from __future__ import annotations

import dataclasses
import json
import shlex

import numpy as np
from drawn import check_drawn, line

from app.cli.main import main
from app.dashboard.frame_loop import ready_line
from app.dashboard.share import settings_json, values_from_json
from app.figures.bandwidth import AXES, bandwidth_figure
from app.figures.presenter import phone_figure
from app.figures.registry import TABS, VIEWS
from app.frames.compute import iter_frames
from app.frames.exports import command_lines
from app.settings.values import Values

SMALL = dict(system="dc-motor", bits=4, steps=100, trajectories=20, realizations=2, identification="BCLS")


def test_the_budget_is_off_by_default_and_then_the_view_says_how_to_start_it():
    assert Values().total_bits == 0.0
    frames = list(iter_frames(Values(**SMALL)))
    assert all(f.budget is None for f in frames)
    fig = bandwidth_figure(None)
    assert "set a bit budget" in fig.layout.annotations[0].text and not fig.data
    assert "Bandwidth" in TABS and any(v.name == "bandwidth" and v.tab == "Bandwidth" for v in VIEWS)
    assert not any(ln.startswith("qsid budget") for ln in command_lines(Values(**SMALL)))


NOISY = Values(**SMALL, noise="0.05", noise_known=True, total_bits=1e5)
_DONE: dict = {}


def noisy_budget():
    """The tab's budget study at :data:`NOISY` (noise-free and with σ = 0.05), computed once."""
    if "bw" not in _DONE:
        _DONE["bw"] = list(iter_frames(NOISY))[-1].budget
    return _DONE["bw"]


def test_the_budget_line_gives_the_rows_the_view_draws(capsys):
    v = NOISY
    assert values_from_json(settings_json(v)) == v  # the settings file carries the budget
    bw = noisy_budget()
    assert bw is not None and bw.noisy is not None and bw.estimator == "bcls"
    line = next(ln for ln in command_lines(v) if ln.startswith("qsid budget"))
    assert "--total-bits=100000.0" in line and "--trajectories" not in line
    assert main([*shlex.split(line)[1:], "--json", "-q"]) == 0
    out = json.loads(capsys.readouterr().out)
    mine = bw.noisy.to_dict()
    assert [r["err_G"] for r in out["rows"]] == [r["err_G"] for r in mine["rows"]]
    assert [r.get("stabilized_fraction") for r in out["rows"]] == [r.get("stabilized_fraction") for r in mine["rows"]]
    assert out["b_knee"] == mine["b_knee"]
    fig = bandwidth_figure(bw)
    assert {t.name.split(":")[0] for t in fig.data} == {"noise-free", "σ = 0.05"}


def test_with_noise_the_two_sides_stand_side_by_side_each_drawing_its_own_rows():
    bw = noisy_budget()
    fig = bandwidth_figure(bw)
    data = check_drawn(fig, "bandwidth")
    lay = fig.layout
    for res, label, (xe, ye, xs, ys) in zip((bw.noise_free, bw.noisy), ("noise-free", "σ = 0.05"), AXES):
        d = res.to_dict()
        ok = [r for r in d["rows"] if r["identifiable"]]
        x, y = line(data, f"{label}: err_G (knee b = {d['b_knee']})", xe)
        assert x.tolist() == [r["bits"] for r in ok] and np.allclose(y, [r["err_G"]["mean"] for r in ok], rtol=1e-12)
        _, y = line(data, f"{label}: predicted (knee b = {d['b_knee_predicted']})", xe)
        assert np.allclose(y, [r["predicted_err_G"] for r in ok], rtol=1e-12)
        _, y = line(data, f"{label}: stabilized", xs)
        assert np.allclose(y, [r["stabilized_fraction"] for r in ok], rtol=1e-12)
        assert {t["yaxis"] for t in data if t["legendgroup"] == label} == {ye, ys}
        knee = next(sh for sh in lay.shapes if sh.name == f"knee {label}")
        assert (knee.xref, knee.x0) == (xe, d["b_knee"])
    assert lay.xaxis.domain[1] < lay.xaxis2.domain[0] and lay.xaxis3.domain == lay.xaxis.domain  # two columns
    assert lay.yaxis3.domain[1] < lay.yaxis.domain[0] and lay.yaxis2.matches == "y"  # share under error, one scale
    errs = [r["err_G"]["mean"] for res in (bw.noise_free, bw.noisy) for r in res.to_dict()["rows"] if r["identifiable"]]
    assert lay.yaxis.range == lay.yaxis2.range and lay.yaxis.tickvals == lay.yaxis2.tickvals
    assert lay.yaxis.range[0] < np.log10(min(errs)) and np.log10(max(errs)) < lay.yaxis.range[1]  # both sides on it
    heads = [a.text for a in lay.annotations]
    assert heads == ["noise-free", "sensor noise σ = 0.05 known to BCLS"]
    # a phone stacks the four panels column by column, each column's title over its error panel, an error
    # panel higher than a share panel as on a laptop
    phone = phone_figure(fig).layout
    doms = [phone[f"yaxis{k}"].domain for k in ("", "3", "2", "4")]
    assert all(phone[f"xaxis{k}"].domain == (0.0, 1.0) for k in ("", "2", "3", "4"))
    assert all(a[0] >= b[1] for a, b in zip(doms, doms[1:]))  # one under the other: y, y3, y2, y4
    assert doms[0][1] - doms[0][0] > 2 * (doms[1][1] - doms[1][0])
    placed = {a.text: a.y for a in phone.annotations if a.text in heads}
    assert placed == {heads[0]: doms[0][1], heads[1]: doms[2][1]}


def test_noise_free_only_the_error_and_the_share_stand_side_by_side():
    bw = dataclasses.replace(noisy_budget(), noisy=None)
    fig = bandwidth_figure(bw)
    data = check_drawn(fig, "bandwidth")
    assert {t["legendgroup"] for t in data} == {"noise-free"} and not fig.layout.annotations
    assert {(t["xaxis"], t["yaxis"]) for t in data} == {("x", "y"), ("x2", "y2")}
    assert fig.layout.xaxis.domain[1] < fig.layout.xaxis2.domain[0] and "xaxis3" not in fig.to_plotly_json()["layout"]


def test_the_ready_line_says_how_long_the_budget_study_took_after_the_curves():
    t = {"current": 1.79, "all": 4.54, "budget": 32.71}  # seconds from the change to each frame drawn
    head = "ready · b = 6 drawn in 1.79 s, all curves in 4.54 s"
    assert ready_line(6, t, budget_done=True, budget_wanted=True) == f"{head} · bit budget study: 28.2 s"
    assert ready_line(6, t, budget_done=False, budget_wanted=True) == f"{head} · computing the bit budget study …"
    assert ready_line(6, t, budget_done=False, budget_wanted=False) == head


def test_bits_per_sample_adds_the_allocation_to_the_view_the_file_and_the_command(capsys):
    v = Values(**SMALL, noise="0.05", noise_known=True, total_bits=1e5, bits_per_sample=12)
    assert Values().bits_per_sample == 0 and values_from_json(settings_json(v)) == v  # off by default; in the file
    bw = list(iter_frames(v))[-1].budget
    assert bw is not None and bw.allocation is not None and bw.allocation_note == ""
    mine = bw.allocation.to_dict()
    line = next(ln for ln in command_lines(v) if "--bits-per-sample=12" in ln)
    assert main([*shlex.split(line)[1:], "--json", "-q"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("channels", "trajectories", "uniform", "proposed", "ratio", "proposed_better"):
        assert out[key] == mine[key], key
    title = bandwidth_figure(bw).layout.title.text
    pro, uni = mine["proposed"], mine["uniform"]
    assert ", ".join(f"{n} {b}" for n, b in zip(mine["channels"], pro["bits"])) in title
    assert f"Measured err_G: proposed {pro['err_G']['mean']:.3g}, uniform {uni['err_G']['mean']:.3g}" in title
    assert f"proposed better in {mine['proposed_better']} of 2" in title and f"{mine['ratio']['median']:.2f}" in title
    # where the allocation does not apply, the view says why instead
    fig = bandwidth_figure(bw)
    lines = phone_figure(fig).layout.annotations[-1].text.split("<br>")  # a phone wraps, joining no line to another
    assert any(ln.startswith("Split of 12 bits per sample") for ln in lines)
    assert any(ln.startswith("Measured err_G") for ln in lines)
    bad = dataclasses.replace(bw, allocation=None, allocation_note="the allocation's error model is for linear plants")
    assert (
        "Per-channel split: the allocation's error model is for linear plants"
        in bandwidth_figure(bad).layout.title.text
    )
