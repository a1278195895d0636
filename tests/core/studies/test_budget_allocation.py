"""Per-channel allocation (qsid_core.studies.budget_allocation): the proposal is the least predicted error over
every integer split, reverse water-filling where the cost is separable, and measured against the uniform split on
the same data it beats it on the presets; bad input is one ConfigError naming the field."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from qsid_core import ConfigError, QuantizerSpec, SweepConfig
from qsid_core.studies import (
    BudgetConfig,
    KoopmanConfig,
    propose_allocation,
    run_allocation,
    run_budget,
    uniform_allocation,
)
from qsid_core.studies.budget_allocation import allocation_cost

DC = SweepConfig(system="dc-motor", steps=100, realizations=6, estimator="bcls", mpc=None)


def _splits(total: int, p: int):
    for cut in itertools.combinations(range(1, total), p - 1):
        parts = np.diff((0, *cut, total))
        if parts.max() <= 32:
            yield tuple(int(v) for v in parts)


def test_uniform_is_as_equal_as_can_be():
    assert uniform_allocation(24, 6) == (4,) * 6
    assert uniform_allocation(24, 5) == (5, 5, 5, 5, 4)
    assert sum(uniform_allocation(17, 4)) == 17


def test_on_a_separable_cost_the_proposal_is_reverse_water_filling():
    """sum_i w_i 4^-b_i: the brute-force optimum, and every channel's w_i 4^-b_i within a factor 4 of the others'
    (the water level) unless it sits at the one-bit floor."""
    w = np.array([1.0, 30.0, 1e-4, 900.0])
    cost = lambda s: float(np.sum(w * 4.0 ** -np.asarray(s)))  # noqa: E731
    got = propose_allocation(cost, 20, 4)
    best = min(_splits(20, 4), key=cost)
    assert cost(got) == pytest.approx(cost(best), rel=1e-12) and sum(got) == 20
    level = w * 4.0 ** -np.asarray(got)
    free = np.asarray(got) > 1
    assert level[free].max() <= 4 * level[free].min()
    assert got[2] == 1  # the channel whose error costs least gets the floor


def test_on_the_predicted_error_the_proposal_is_the_best_split():
    study = replace(SweepConfig(system="examples/plant.toml", steps=100, estimator="bcls", mpc=None), trajectories=50)
    cost = allocation_cost(study)
    got = propose_allocation(cost, 15, 3)
    best = min(_splits(15, 3), key=cost)
    assert cost(got) <= cost(best) * (1 + 1e-9)


@pytest.mark.parametrize("system", ["dc-motor", "boeing747"])
def test_measured_the_proposal_beats_the_uniform_split_on_the_presets(system):
    res = run_allocation(BudgetConfig(2e6, replace(DC, system=system), bits_per_sample=24))
    d = res.to_dict()
    assert sum(d["proposed"]["bits"]) == sum(d["uniform"]["bits"]) == 24
    assert d["trajectories"] == int(2e6 // (100 * 24))
    u, p = d["uniform"]["err_G"]["mean"], d["proposed"]["err_G"]["mean"]
    assert p < 0.9 * u and d["proposed_better"] >= 5
    assert d["proposed"]["predicted_err_G"] < d["uniform"]["predicted_err_G"]
    for name in ("uniform", "proposed"):  # the prediction the split was chosen on, within a factor 2 of the measurement
        assert 0.5 <= d[name]["predicted_err_G"] / d[name]["err_G"]["mean"] <= 2.0, (name, d[name])
    ratio = res.ratios()
    assert d["ratio"]["mean"] == pytest.approx(float(np.mean(ratio)))


@pytest.mark.parametrize(
    "kw,field",
    [
        ({"bits_per_sample": 3}, "bits per sample"),  # fewer than one bit per channel (dc-motor: 5)
        ({"bits_per_sample": 2.5}, "bits per sample"),
        ({"bits_per_sample": True}, "bits per sample"),
        ({"bits_per_sample": 33 * 5}, "bits per sample"),
        ({"bits_per_sample": 24, "study": replace(DC, quantizer=QuantizerSpec(dither="none"))}, "bits per sample"),
        ({"bits_per_sample": 24, "study": KoopmanConfig()}, "bits per sample"),
    ],
)
def test_bad_settings_are_one_config_error_naming_the_field(kw, field):
    kw = {"total_bits": 1e6, "study": DC, **kw}
    with pytest.raises(ConfigError, match=field) as e:
        BudgetConfig(**kw)
    assert isinstance(e.value, ValueError) and "\n" not in str(e.value)


def test_a_budget_too_small_or_the_wrong_runner_is_one_config_error():
    with pytest.raises(ConfigError, match="total bits: 2000 bits at 24 bits per sample buy 0 run"):
        run_allocation(BudgetConfig(2000, DC, bits_per_sample=24))
    with pytest.raises(ConfigError, match="bits per sample"):
        run_budget(BudgetConfig(1e6, DC, bits_per_sample=24))
    with pytest.raises(ConfigError, match="bits per sample"):
        run_allocation(BudgetConfig(1e6, DC))
