"""A study given a budget ends with its budget study (qsid_core.studies.study_budget): noise-free and, with sensor
noise, noisy; cancelled, nothing; a budget that identifies nothing is said, not raised."""

from __future__ import annotations

from dataclasses import replace

from qsid_core import QuantizerSpec, SweepConfig
from qsid_core.studies import Study, bandwidth, bandwidth_key, run_allocation, run_budget
from qsid_core.studies.budget import BudgetConfig

CFG = SweepConfig(system="dc-motor", bits=(2, 4, 6), realizations=2, trajectories=20, steps=100, mpc=None)


def test_the_budget_frame_comes_last_with_both_sides_equal_to_run_budget():
    cfg = replace(CFG, noise=(0.05,), noise_known=True, estimator="bcls")
    frames = list(Study(cfg, budget=1e5).frames(4))
    assert [f.stage for f in frames] == ["current", "curves", "budget"]
    bw = frames[-1].budget
    assert bw is not None and bw.estimator == "bcls" and bw.noisy is not None
    again = run_budget(BudgetConfig(1e5, cfg)).to_dict()
    got = bw.noisy.to_dict()
    assert [r["err_G"] for r in got["rows"]] == [r["err_G"] for r in again["rows"]]
    assert bw.noise_free.to_dict()["config"]["noise"] == [0.0]
    assert [f.stage for f in Study(CFG).frames(4)] == ["current", "curves"]  # no budget, no budget frame


def test_cancelled_is_none_and_a_hopeless_budget_is_an_error_line():
    assert bandwidth(CFG, 1e5, cancel=lambda: True) is None
    bw = bandwidth(CFG, 10)
    assert bw is not None and bw.noise_free is None and bw.error.startswith("total bits: 10 bits identify nothing")
    notes = bandwidth(replace(CFG, input_bits="exact"), 1e5)
    assert notes is not None and "not used" in notes.notes[0] and notes.noise_free is not None


def test_a_study_of_the_same_settings_takes_the_budget_from_the_cache():
    cache: dict = {}
    first = list(Study(CFG, cache=cache, budget=1e5).frames(4))[-1].budget
    again = list(Study(replace(CFG, trajectories=30), cache=cache, budget=1e5).frames(2))[-1].budget
    assert first is not None and again is first  # another current b, another sweep size: the same budget study
    other = list(Study(replace(CFG, steps=50), cache=cache, budget=1e5).frames(4))[-1].budget
    assert other is not None and other is not first
    assert bandwidth_key(CFG, 1e5, "ls") != bandwidth_key(CFG, 2e5, "ls") != bandwidth_key(CFG, 2e5, "bcls")


def test_bits_per_sample_add_the_allocation_or_say_why_not():
    bw = bandwidth(CFG, 1e5, bits_per_sample=9)
    assert bw is not None and bw.allocation is not None and bw.allocation_note == ""
    again = run_allocation(BudgetConfig(1e5, CFG, bits_per_sample=9)).to_dict()
    got = bw.allocation.to_dict()
    assert {k: got[k] for k in ("proposed", "uniform", "ratio")} == {
        k: again[k] for k in ("proposed", "uniform", "ratio")
    }
    tpdf = bandwidth(replace(CFG, quantizer=QuantizerSpec(dither="tpdf")), 1e5, bits_per_sample=9)
    assert tpdf is not None and tpdf.allocation is None and "subtractive dither" in tpdf.allocation_note
    assert tpdf.noise_free is not None  # the budget study itself still there
    assert bandwidth(CFG, 1e5).allocation is None  # none asked
    assert bandwidth_key(CFG, 1e5, "ls", 9) != bandwidth_key(CFG, 1e5, "ls")
    frames = list(Study(CFG, budget=1e5, bits_per_sample=9).frames(4))
    assert frames[-1].budget.allocation.to_dict()["proposed"] == got["proposed"]
