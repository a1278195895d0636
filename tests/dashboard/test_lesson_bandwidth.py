"""The bandwidth lessons' claims (``bandwidth``: Boeing 747; ``bandwidth-koopman``: Van der Pol), asserted on the
numbers the dashboard computes at each lesson's own settings (lesson -> Values -> iter_frames -> the engine's
Study with the budget, the dashboard's path), and the bandwidth view drawing exactly those numbers."""

from __future__ import annotations

import numpy as np
import pytest

from app.figures.bandwidth import bandwidth_figure
from app.frames.compute import iter_frames
from app.lessons.table import get_lesson, lesson_values

pytestmark = pytest.mark.slow  # two budget studies of 16 word lengths with their loops

_BW: dict = {}


def budget(name: str):
    if name not in _BW:
        frames = list(iter_frames(lesson_values(name)))
        assert frames[-1].complete and frames[-1].budget is not None
        assert all(f.budget is None for f in frames[:-1])  # the budget comes last, after the curves
        _BW[name] = frames[-1].budget
    return _BW[name]


def rows(res) -> dict:
    return {r["bits"]: r for r in res.to_dict()["rows"]}


def per_bit(r: dict, lo: int, hi: int) -> float:
    return float((r[lo]["err_G"]["mean"] / r[hi]["err_G"]["mean"]) ** (1 / (hi - lo)))


def test_boeing_noise_free_finer_words_win_noisy_knee_near_6_loops_all_stabilize():
    bw = budget("bandwidth")
    text = get_lesson("bandwidth").text
    assert bw.estimator == "bcls" and bw.total_bits == 2e6 and not bw.notes
    free, noisy = rows(bw.noise_free), rows(bw.noisy)
    for r in (free, noisy):
        assert r[1]["trajectories"] == 3333 and r[16]["trajectories"] == 208  # "3333 at b = 1, 208 at b = 16"
        assert all(row["stabilized_fraction"] == 1.0 for row in r.values())  # every loop, every b
    assert "3333 at b = 1, 208 at b = 16" in text
    assert bw.noise_free.b_knee == bw.noise_free.b_best == 16  # "the knee is b = 16"
    assert 1.6 <= per_bit(free, 4, 16) <= 2.5  # "about 2x per bit"
    assert 5 <= bw.noisy.b_knee <= 7  # "near b = 6"
    assert bw.noisy.b_knee_predicted is not None and abs(bw.noisy.b_knee_predicted - bw.noisy.b_knee) <= 1
    least = min(r["err_G"]["mean"] for r in noisy.values())
    assert noisy[16]["err_G"]["mean"] > 1.05 * least  # "finer words only cost runs"
    sigma = 0.1  # "the widest channels' quantization error eps/sqrt(12) is down to the noise's size (within 3x)"
    q = float(np.max(noisy[bw.noisy.b_knee]["eps"][:4])) / np.sqrt(12)
    assert sigma / 3 <= q <= 3 * sigma
    assert float(np.max(noisy[bw.noisy.b_knee - 2]["eps"][:4])) / np.sqrt(12) > 3 * sigma  # and not before


def test_van_der_pol_finer_words_win_loops_bounded_within_radius_from_b3():
    bw = budget("bandwidth-koopman")
    assert bw.noisy is None and bw.error == ""
    r = rows(bw.noise_free)
    assert r[1]["trajectories"] == 1666 and r[16]["trajectories"] == 104  # "1666 at b = 1, 104 at b = 16"
    assert "1666 at b = 1, 104 at b = 16" in get_lesson("bandwidth-koopman").text
    assert bw.noise_free.b_knee == 16
    assert 1.6 <= per_bit(r, 3, 16) <= 2.5
    for b, row in r.items():
        oc = row["closed_loop_outcomes"]
        assert row["stabilized_fraction"] == 0.0 and oc["converged"] == 0, b  # "converge at no b"
        if b >= 3:
            assert oc["bounded"] == row["within_radius"] == sum(oc.values()), b  # all within the radius
            assert row["settled_offset"]["median"] > 1e-6
    assert r[1]["within_radius"] == 0  # "at b = 1 none"


@pytest.mark.parametrize("name", ["bandwidth", "bandwidth-koopman"])
def test_the_view_draws_the_numbers_it_claims(name):
    bw = budget(name)
    fig = bandwidth_figure(bw)
    sides = [(bw.noise_free, "noise-free"), *([(bw.noisy, "σ = 0.1")] if bw.noisy else [])]
    for res, label in sides:
        d = res.to_dict()
        ok = [x for x in d["rows"] if x["identifiable"]]
        err = next(t for t in fig.data if t.name.startswith(f"{label}: err_G"))
        assert list(err.x) == [x["bits"] for x in ok]
        assert np.allclose(err.y, [x["err_G"]["mean"] for x in ok]) and f"knee b = {d['b_knee']}" in err.name
        share = next(t for t in fig.data if t.name == f"{label}: stabilized")
        assert np.allclose(share.y, [x["stabilized_fraction"] for x in ok])
        knee = next(s for s in fig.layout.shapes if s.name == f"knee {label}")
        assert knee.x0 == knee.x1 == d["b_knee"]
    assert len(fig.layout.shapes) == len(sides)
