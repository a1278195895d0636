"""The nonlinear lessons' claims (``koopman``, ``bias-variance``), asserted on the numbers the dashboard computes at
each lesson's own settings (lesson -> Values -> koopman_config -> KoopmanExperiment, the dashboard's path); the
full-scale ratio the ``koopman`` lesson quotes on the CLI's own sweep."""

from __future__ import annotations

import dataclasses
import inspect

import numpy as np
import pytest

from app.figures.lifted_scene import lifted_scene
from app.lessons.table import get_lesson, lesson_values
from app.settings.config import koopman_config
from qsid_core.studies import KoopmanConfig, KoopmanExperiment, run_koopman_sweep

pytestmark = pytest.mark.slow  # 400 x 100 samples, 10 realizations, Koopman MPC loops

_EX: dict = {}


def experiment(name: str) -> KoopmanExperiment:
    if name not in _EX:
        cfg, ests = koopman_config(lesson_values(name))
        assert ests == ("ls", "bcls")
        _EX[name] = KoopmanExperiment(cfg)
    return _EX[name]


def err(ex: KoopmanExperiment, b: int, est: str) -> dict:
    return ex.models(b, est).row["err_G"]


def test_the_nonlinear_lessons_are_short_and_name_their_settings():
    for name in ("koopman", "bias-variance"):
        les = get_lesson(name)
        assert 2 <= les.text.count(". ") + 1 <= 5
        cfg, _ = koopman_config(lesson_values(name))
        assert (cfg.trajectories, cfg.steps, cfg.realizations) == (400, 100, 10) and cfg.lifting == "poly:3"
        assert les.plot.startswith("koopman-")


def test_koopman_ls_on_its_limit_bcls_15_to_40_times_lower_and_both_agree_at_fine_b():
    ex = experiment("koopman")
    assert ex.config.system == "van-der-pol" and lesson_values("koopman").bits == 3
    for b in range(2, 8):  # LS on its large-data limit, within 5 %
        row = ex.models(b, "ls").row
        assert abs(row["err_G"]["mean"] / row["large_data"]["err_G"] - 1) < 0.05, b
    for b in range(3, 7):
        ratio = err(ex, b, "ls")["mean"] / err(ex, b, "bcls")["mean"]
        assert 15 <= ratio <= 40, (b, ratio)
    for b in range(11, 17):
        ls, bc = err(ex, b, "ls")["mean"], err(ex, b, "bcls")["mean"]
        assert abs(ls / bc - 1) < 0.10, b


def test_koopman_full_scale_ratio_is_about_50():
    cfg = KoopmanConfig(system="van-der-pol", lifting="poly:3", bits=(3,), mpc=None)
    assert (cfg.trajectories, cfg.steps) == (2000, 100)
    ls = run_koopman_sweep(cfg).rows[0]["err_G"]["mean"]
    bc = run_koopman_sweep(dataclasses.replace(cfg, estimator="bcls")).rows[0]["err_G"]["mean"]
    assert 40 <= ls / bc <= 65, ls / bc


def test_the_lifted_scene_draws_the_limit_cycle_and_the_loops_at_b3():
    ex = experiment("koopman")
    flow = ex.free_flow()
    assert flow.shape[0] == 9 and ex.loops(3, "ls") is not None and ex.loops(3, "bcls") is not None
    # what the text says is drawn green: the plant's own flow from a grid of starts, each but the one at the
    # origin (an equilibrium) winding onto the limit cycle (|x1| up to about 2 over its last laps)
    origin = np.all(flow[:, 0] == 0, axis=1)
    assert origin.sum() == 1 and np.all(flow[origin] == 0)
    reach = np.abs(flow[~origin, -60:, 0]).max(axis=1)
    assert np.all(np.abs(reach - 2.0) < 0.1), reach
    text = get_lesson("koopman").text
    assert "the plant's own flow (green, u = 0)" in text and "each but the one at the origin winding onto" in text
    assert "green: the plant's own flow (u = 0)" in inspect.getsource(lifted_scene)  # the scene's caption


def test_bias_variance_bcls_lower_mean_larger_spread_fewer_loops_within_the_radius_at_b2():
    ex = experiment("bias-variance")
    assert ex.config.system == "pendulum" and lesson_values("bias-variance").bits == 2
    ls, bc = err(ex, 2, "ls"), err(ex, 2, "bcls")
    assert bc["mean"] < 1 < 1.4 < ls["mean"]
    assert bc["std"] > 2 * ls["std"]
    ls_loops, bc_loops = ex.loops(2, "ls"), ex.loops(2, "bcls")
    cl, cb = int(ls_loops.within_radius.sum()), int(bc_loops.within_radius.sum())
    assert cl == 10 and cb <= 8
    # none converges: every loop that does not diverge settles at an offset (bounded), as the reference's does
    assert ls_loops.counts()["converged"] == 0 == bc_loops.counts()["converged"]
    assert ex.reference_loop().outcome == ["bounded"]


def test_bias_variance_at_b3_both_end_within_the_radius_and_bcls_wins():
    ex = experiment("bias-variance")
    assert ex.loops(3, "ls").within_radius.sum() == 10 == ex.loops(3, "bcls").within_radius.sum()
    ls, bc = ex.models(3, "ls").row, ex.models(3, "bcls").row
    assert bc["err_G"]["mean"] < ls["err_G"]["mean"]
    assert bc["prediction_error"]["mean"] < ls["prediction_error"]["mean"]
