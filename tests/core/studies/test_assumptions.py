import numpy as np
import pytest

from qsid_core import LETTER_QUANTIZER, Experiment, QuantizerSpec, SweepConfig
from qsid_core.studies.assumptions import OVERLOAD_EFFECT_RATIO, finite_data_fluctuation

SMALL = dict(trajectories=20, steps=300, realizations=3, mpc=None)


@pytest.mark.slow
def test_letter_quantizer_overload_judged_by_its_effect_and_guard_band_has_none():
    """dc-motor, 20 x 300 samples, b = 2: the letter's quantizer overloads 4 % of the entries, but the clipped
    samples move A^ by 0.07 against a fluctuation of 0.9: harmless at this data size; the guard band clips nothing."""
    letter = Experiment(SweepConfig(system="dc-motor", bits=(2,), quantizer=LETTER_QUANTIZER, **SMALL)).assumptions(2)
    guard = Experiment(SweepConfig(system="dc-motor", bits=(2,), **SMALL)).assumptions(2)
    assert letter.overload_fraction > 0.01 and letter.overload_effect_A > 0
    assert letter.no_overload == (
        OVERLOAD_EFFECT_RATIO * letter.overload_effect_A <= letter.fluctuation_A
        and OVERLOAD_EFFECT_RATIO * letter.overload_effect_B <= letter.fluctuation_B
    )
    assert letter.no_overload and letter.bcls_holds and not any(n.startswith("overload") for n in letter.notes)
    assert guard.overload_fraction == 0.0 and guard.overload_effect_A < 1e-12 and guard.no_overload


def test_fixed_range_too_small_overloads():
    q = QuantizerSpec(range_mode="fixed", fixed_range=(-0.5, 0.5))
    a = Experiment(SweepConfig(system="boeing747", bits=(6,), quantizer=q, **SMALL)).assumptions(6)
    assert not a.no_overload and a.overload_fraction > 0.1
    assert any(n.startswith("overload: the range ±0.5 (guard band) clips") for n in a.notes)


def test_large_data_flag_follows_data_length():
    """Boeing, shared range: b = 4 bias (0.75) dwarfs the fluctuation even for little data; b = 12 needs more."""
    few = Experiment(
        SweepConfig(system="boeing747", bits=(4, 12), quantizer=QuantizerSpec(range_mode="shared"), **SMALL)
    )
    assert few.assumptions(4).large_data and few.assumptions(4).theorem1_holds
    a12 = few.assumptions(12)
    assert not a12.large_data and a12.fluctuation_A > a12.bias_A / 3
    assert a12.to_dict()["large_data"] is False and isinstance(a12.to_dict()["notes"], list)


def test_predicted_fluctuation_matches_realization_spread():
    """The predicted O(eps/sqrt(T)) spread is within a factor 2 of the measured spread of A^ over dither."""
    ex = Experiment(SweepConfig(system="boeing747", bits=(8,), realizations=12, trajectories=50, steps=400, mpc=None))
    i = ex.identification(8)
    measured = np.sqrt((i.A_hat.std(0) ** 2).sum())
    fA, _ = finite_data_fluctuation(ex.system.G, ex.prepared.exact.PP, i.eps)
    assert 0.5 < measured / fA < 2.0, (measured, fA)


def test_fluctuation_scales_like_eps_over_sqrt_T():
    rng = np.random.default_rng(0)
    G = rng.normal(size=(2, 3))
    M = rng.normal(size=(3, 3))
    PP = M @ M.T + np.eye(3)
    eps = np.array([0.1, 0.2, 0.3])
    f1 = finite_data_fluctuation(G, PP, eps)
    f2 = finite_data_fluctuation(G, 4 * PP, 2 * eps)  # 4x the samples, twice the cell: same
    assert f1 == pytest.approx(f2)


def test_data_extremes_match_the_regression_matrices_and_decide_clipping_alike():
    from qsid_core.plant.data import simulate
    from qsid_core.plant.systems import get_system
    from qsid_core.studies.clipping import clipping_effect, clips_nothing

    sysm = get_system("dc-motor")
    data = simulate(sysm, trajectories=7, steps=30, seed=3)
    Psi, Xp = data.matrices()
    ext = data.extremes()
    assert ext is data.extremes()  # computed once
    for got, want in zip(ext, (Psi.min(axis=1), Psi.max(axis=1), Xp.min(axis=1), Xp.max(axis=1))):
        np.testing.assert_array_equal(got, want)
    top = np.maximum(np.abs(Psi).max(axis=1), 1e-9)
    for scale in (0.3, 0.9, 1.5, 4.0):  # ranges that clip a lot, a little, and not at all
        lo_q = -scale * top
        eps = 2 * scale * top / 16
        shift = clipping_effect(sysm.G, Psi, Xp, lo_q, eps, 4)
        assert clips_nothing(ext, lo_q, eps, 4) == (not np.any(shift))
        given = clipping_effect(sysm.G, Psi, Xp, lo_q, eps, 4, 1 / 12, ext, (Psi @ Psi.T, Xp @ Psi.T))
        np.testing.assert_allclose(given, shift, rtol=1e-9, atol=1e-12)  # known extremes and Grams: same effect


def test_overload_effect_needs_no_quantized_data_and_matches_the_assessment():
    from qsid_core.quantization.quantize import QuantizerSpec
    from qsid_core.studies.config import SweepConfig
    from qsid_core.studies.experiment import Experiment

    for q in (QuantizerSpec(guard=False, range_mode="fixed", fixed_range=(-1.0, 1.0)), QuantizerSpec()):
        ex = Experiment(SweepConfig(trajectories=6, steps=40, realizations=2, mpc=None, quantizer=q))
        for b in (2, 5):
            effect = ex.overload_effect(b)  # before any quantization
            assert effect is ex.overload_effect(b)  # cached
            a = ex.assumptions(b)
            nA = np.linalg.norm(ex.system.A)
            assert a.overload_effect_A == pytest.approx(np.linalg.norm(effect[:, : ex.system.n]) / nA)
            if q.range_mode == "fixed":
                assert np.any(effect)  # +-1 clips the motor's data
