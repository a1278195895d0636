"""The Control tab's "how many bits" view, the bound view's no-bound shading and the loops' plain-words counts."""

import numpy as np
import pytest

from app.figures.bits_needed import answers, bits_figure
from app.figures.bound import bound_figure
from app.figures.time_series import failure_text
from app.figures.traces import CURRENT_B, move_current_bits
from qsid_core.control.loop_results import ClosedLoops
from qsid_core.studies.config import SweepConfig
from qsid_core.studies.experiment import Experiment
from qsid_core.studies.sweep import run_sweep

CFG = SweepConfig(system="boeing747", bits=(1, 2, 3, 4, 6, 8, 10), realizations=8, trajectories=50, steps=300)


def _series():
    ex = Experiment(CFG)
    res = run_sweep(CFG, experiment=ex)
    return ex, res, {"LS": [res.summary(b).to_dict() for b in res.bits]}


def test_bits_view_marks_the_three_answers_and_keeps_them_when_b_moves():
    ex, res, series = _series()
    ans = answers(series, float(res.true_loop.cost[0]), ex, 0.95, 0.01)
    a = ans["LS"]
    fig = bits_figure(ans, current_bits=4)
    assert a.sentence.split(";")[0][:40] in fig.layout.title.text.replace("<br>", " ")
    marked = {sh.x0 for sh in fig.layout.shapes if sh.x0 == sh.x1 and sh.name != CURRENT_B}
    assert marked == {b for b in (a.b_observed, a.b_robust, a.b_letter) if b is not None} and marked
    stab = next(t for t in fig.data if t.name == "LS stabilized")
    assert list(stab.x) == list(res.bits) and all(0 <= y <= 100 for y in stab.y)
    assert stab.y[list(stab.x).index(2)] < 100  # the Boeing at b = 2: loops that do not converge
    move_current_bits(fig, 8)
    assert {sh.x0 for sh in fig.layout.shapes if sh.name == CURRENT_B} == {8}
    assert {sh.x0 for sh in fig.layout.shapes if sh.x0 == sh.x1 and sh.name != CURRENT_B} == marked


def test_bound_view_shades_where_the_proof_gives_nothing_and_marks_x0():
    rows = [
        {
            "bits": b,
            "ultimate_bound": d,
            "rho": 4.3,
            "bound_self_consistent": d < 4.3,
            "final_state_norm": {"mean": 1e-3, "max": 2e-3},
        }
        for b, d in ((1, 100.0), (2, 50.0), (3, 2.0), (4, 0.5))
    ]
    fig = bound_figure({"LS": rows}, current_bits=3, x0_norm=1.41)
    rects = [sh for sh in fig.layout.shapes if sh.type == "rect"]
    assert [(r.x0, r.x1) for r in rects] == [(0.5, 2.5)]
    texts = [a.text for a in fig.layout.annotations]
    assert any(t.startswith("‖x0‖ = 1.41") for t in texts) and not any("no bound" in t for t in texts)
    assert [tr.name for tr in fig.data if tr.name and "no bound" in tr.name] == ["shaded: δ ≥ ρ, no bound"]


def test_time_series_title_counts_loops_that_do_not_converge():
    lp = ClosedLoops.empty(4, 5, 2, 1)
    lp.outcome = ["converged", "bounded", "bounded", "diverged"]
    lp.failure = ["", "", "", "diverged"]
    text = failure_text({"LS": lp})
    assert "LS 1/4 failed (diverged; not drawn)" in text
    assert "LS 3/4 did not converge on the true plant (2 bounded, 1 diverged)" in text
    lp.outcome = ["converged"] * 4
    lp.failure = [""] * 4
    assert failure_text({"LS": lp}) == ""
    assert np.isnan(lp.cost).all()


@pytest.mark.slow
def test_dashboard_summary_counts_the_boeing_loops_that_do_not_converge():
    """Paper scale, Boeing, b = 2 (the guard band default): the summary says how many loops did not converge."""
    from app.dashboard.session import iter_frames
    from app.frames.cache import SharedCache
    from app.frames.summary import summary_markdown
    from app.settings.values import Values

    v = Values(system="boeing747", bits=2, realizations=50, trajectories=200, steps=1000, identification="LS")
    cur = next(f for f in iter_frames(v, SharedCache(), chunk=16, min_interval=0.0) if f.stage == "current")
    text = summary_markdown(cur)
    oc = cur.rows["LS"][2]["closed_loop_outcomes"]
    assert oc["converged"] <= 10 and f"**{50 - oc['converged']}/50 did not converge**" in text
    assert "not a bound here" in text  # the letter's delta >= rho at b = 2


def test_cost_view_says_where_loops_did_not_converge():
    from app.figures.cost import cost_figure

    rows = [
        {
            "bits": 1,
            "mpc_cost": {"mean": 3.0, "std": 0.1},
            "closed_loop_outcomes": {"converged": 2, "bounded": 48, "diverged": 0, "failed": 0},
        },
        {
            "bits": 2,
            "mpc_cost": {"mean": 2.0, "std": 0.1},
            "closed_loop_outcomes": {"converged": 50, "bounded": 0, "diverged": 0, "failed": 0},
        },
    ]
    texts = [a.text for a in cost_figure({"LS": rows}, true_cost=1.9).layout.annotations]
    assert "did not converge: LS: b=1 48/50" in texts
    assert not any(
        "did not converge" in t
        for t in (a.text for a in cost_figure({"LS": rows[1:]}, true_cost=1.9).layout.annotations)
    )
