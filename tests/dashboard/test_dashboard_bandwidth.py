"""The bit budget in the dashboard: a setting (panel, settings file), the tab's study ending with its budget study,
the bandwidth view (with and without a result) and "as a command": the ``qsid budget`` line gives the very rows
the view draws."""

from __future__ import annotations

import json
import shlex

from app.cli.main import main
from app.dashboard.share import settings_json, values_from_json
from app.figures.bandwidth import bandwidth_figure
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


def test_the_budget_line_gives_the_rows_the_view_draws(capsys):
    v = Values(**SMALL, noise="0.05", noise_known=True, total_bits=1e5)
    assert values_from_json(settings_json(v)) == v  # the settings file carries the budget
    last = list(iter_frames(v))[-1]
    bw = last.budget
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
