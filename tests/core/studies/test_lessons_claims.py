"""The claims a teacher's lessons make, asserted on the engine's numbers (each test a few seconds)."""

import numpy as np
import pytest

from qsid_core import LETTER_QUANTIZER, Experiment, QuantizerSpec, SweepConfig, run_sweep


def _errors(system, b, quantizer, estimator, realizations, trajectories=200, steps=1000):
    ex = Experiment(
        SweepConfig(
            system=system,
            bits=(b,),
            realizations=realizations,
            trajectories=trajectories,
            steps=steps,
            quantizer=quantizer,
            mpc=None,
        )
    )
    return ex, ex.identification(b, estimator)


@pytest.mark.parametrize("guard", [False, True])
def test_why_dither_bcls_needs_known_noise(guard):
    """Boeing, fixed range [-20, 20], b = 3, 200 x 1000: BCLS with subtractive dither is far more accurate
    than BCLS without dither (measured 0.019 vs 0.66 for A without guard band), while LS is poor in both."""
    fixed = dict(range_mode="fixed", fixed_range=(-20, 20), guard=guard)
    ex_d, bc_d = _errors("boeing747", 3, QuantizerSpec(dither="subtractive", **fixed), "bcls", 2)
    ex_n, bc_n = _errors("boeing747", 3, QuantizerSpec(dither="none", **fixed), "bcls", 1)
    ls_d, ls_n = ex_d.identification(3, "ls"), ex_n.identification(3, "ls")
    assert bc_d.err_A.mean() < 0.05 and bc_d.err_B.mean() < 0.06
    assert bc_n.err_A.mean() > 0.5 and bc_n.err_B.mean() > 0.5
    assert bc_n.err_A.mean() > 20 * bc_d.err_A.mean()
    assert ls_d.err_A.mean() > 0.7 and ls_n.err_A.mean() > 0.7  # LS alone: the O(eps^2) bias is huge at b = 3
    # the engine says why: BCLS's hypotheses hold with dither, not without
    assert ex_d.assumptions(3).bcls_holds and not ex_n.assumptions(3).bcls_holds
    assert bc_n.effective_realizations == 1


def test_theorem1_matches_long_simulation_with_guard_band():
    """Boeing (stationary), per-channel range with guard band, T = 10^6: mean LS error on Theorem 1's line
    where the engine says the hypotheses hold; above it where it flags the finite-data regime."""
    ex = Experiment(
        SweepConfig(system="boeing747", bits=(2, 4, 6), realizations=3, trajectories=1000, steps=1000, mpc=None)
    )
    ex.moments((2, 4, 6))
    for b in (2, 4):
        i, th, a = ex.identification(b), ex.theory(b), ex.assumptions(b)
        assert a.theorem1_holds and a.stationary and a.no_overload and a.large_data
        assert i.err_A.mean() == pytest.approx(th.err_A, rel=0.03)
    assert ex.identification(2).err_B.mean() == pytest.approx(ex.theory(2).err_B, rel=0.03)
    a6 = ex.assumptions(6)
    assert not a6.large_data and not a6.theorem1_holds
    assert ex.identification(6).err_B.mean() > 1.3 * ex.theory(6).err_B  # finite data: above the line


def test_finite_data_error_falls_0p3_per_bit():
    """dc-motor (the letter's Fig. 1 setting, guard band), b = 4..12: log10 error falls ~0.30 per bit,
    and the engine flags every b as finite-data (and the motor as non-stationary)."""
    res = run_sweep(SweepConfig(system="dc-motor", bits="4:12", realizations=5, mpc=None))
    assert -0.36 <= res.slope_A <= -0.26 and -0.36 <= res.slope_B <= -0.26, (res.slope_A, res.slope_B)
    assert not any(res.assumptions[b].large_data for b in res.bits)
    assert not any(res.assumptions[b].stationary for b in res.bits)
    assert all(res.assumptions[b].bcls_holds for b in res.bits)


def test_integrator_makes_theorem1_inapplicable():
    """The dc-motor angle is an integrator: eigenvalue 1, so Psi Psi^T / T has no limit; Boeing is stationary."""
    m = Experiment(SweepConfig(system="dc-motor", bits=(4,), realizations=1, trajectories=10, steps=100, mpc=None))
    bo = Experiment(SweepConfig(system="boeing747", bits=(4,), realizations=1, trajectories=10, steps=100, mpc=None))
    am, ab = m.assumptions(4), bo.assumptions(4)
    assert not am.stationary and am.spectral_radius == pytest.approx(1.0, abs=1e-9)
    assert ab.stationary and ab.spectral_radius < 1
    assert any("unit circle" in n for n in am.notes)


def _boeing_fixed(limits, bits, realizations=3):
    q = QuantizerSpec(dither="subtractive", range_mode="fixed", fixed_range=limits, guard=False)
    ex = Experiment(SweepConfig(system="boeing747", bits=bits, realizations=realizations, quantizer=q, mpc=None))
    ex.moments(bits)
    return ex


def test_overload_judged_by_its_effect_names_clipping_as_the_floor():
    """Boeing, range ±20, no guard band, 200 x 1000: 0.05 % of the samples overload at every b. At b = 3 that is
    harmless (effect below a third of the fluctuation); from b = 10 on LS and BCLS level off at the predicted
    clipping effect (1.86e-4, 7.5e-4) and the engine names clipping, not the data length, as the cause."""
    ex = _boeing_fixed((-20, 20), (3, 10, 12, 14))
    a3 = ex.assumptions(3)
    assert 3e-4 < a3.overload_fraction < 1e-3 and a3.no_overload and a3.bcls_holds
    for b in (10, 12, 14):
        a = ex.assumptions(b)
        assert 3e-4 < a.overload_fraction < 1e-3 and not a.no_overload and not a.bcls_holds
        assert a.overload_effect_A > 2 * a.fluctuation_A and a.overload_effect_B > 3 * a.fluctuation_B
    a12 = ex.assumptions(12)
    note = next(n for n in a12.notes if n.startswith("overload:"))
    assert "the range ±20 (no guard band) clips 0.053 % of the samples" in note
    assert "not the data length, sets the error floor" in note
    for b in (12, 14):
        for est in ("ls", "bcls"):
            i = ex.identification(b, est)
            assert i.err_A.mean() == pytest.approx(ex.assumptions(b).overload_effect_A, rel=0.05), (b, est)
            assert i.err_B.mean() == pytest.approx(ex.assumptions(b).overload_effect_B, rel=0.05), (b, est)


def test_wider_range_removes_the_floor():
    """The same with --limits=-40,40: no overload, and the LS error keeps falling past the ±20 floor (measured
    1.2e-4, 2.8e-6 at b = 12, 16 with 3 realizations: 0.41 decades per bit, the O(eps^2) bias giving way to
    the O(eps) fluctuation)."""
    ex = _boeing_fixed((-40, 40), (12, 14, 16))
    assert all(ex.assumptions(b).overload_fraction == 0 and ex.assumptions(b).no_overload for b in (12, 14, 16))
    e = {b: ex.identification(b, "ls").err_A.mean() for b in (12, 14, 16)}
    assert e[16] < e[14] < e[12] and e[16] < 1e-5  # far below the ±20 floor of 1.86e-4
    assert -0.55 < np.log10(e[16] / e[12]) / 4 < -0.25


def test_letter_boeing_overload_moves_b_not_a():
    """The letter's Boeing settings at b = 2: the clipped samples move B^ by ~7x its fluctuation but A^ by 1/20 of
    it, so Theorem 1 holds for A^ (LS on the line within 1 %) and not for B^."""
    ex = Experiment(SweepConfig(system="boeing747", bits=(2,), realizations=5, quantizer=LETTER_QUANTIZER, mpc=None))
    a = ex.assumptions(2)
    assert a.no_overload_A and not a.no_overload_B and a.theorem1_holds_A and not a.theorem1_holds_B
    assert a.overload_effect_B > 3 * a.fluctuation_B and a.overload_effect_A < a.fluctuation_A / 3
    assert ex.identification(2, "ls").err_A.mean() == pytest.approx(a.bias_A, rel=0.01)


def test_quantizer_error_against_signal_sawtooth_and_band():
    """Plain quantization error is a deterministic sawtooth of x (99.6 % of its variance fixed by the cell
    position, at every b), the dithered one a band independent of x (< 1 %), while the correlation with x
    alone shrinks to ~0 at fine b for both; the quantizer view draws both against x with that reading."""
    from app.figures.quantizer import dependence_text, quantizer_figure
    from qsid_core.quantization.quantizer_demo import quantizer_demo

    x = np.random.default_rng(1).uniform(-1, 1, 20000)
    for b in (2, 8):
        d = quantizer_demo(x, -1, 1, b)
        assert d.cell_dependence_plain > 0.99 and d.cell_dependence_dithered < 0.01
        pos = np.mod((d.scatter_x - d.lo_q) / d.eps, 1.0)
        np.testing.assert_allclose(d.scatter_plain, d.eps * (pos - 0.5), atol=1e-9 * d.eps)  # the sawtooth
        assert np.all(np.abs(d.scatter_dithered) <= d.eps / 2 + 1e-12)  # the band
    assert abs(d.corr_plain) < 0.05  # correlation with x alone misses the sawtooth at b = 8
    fig = quantizer_figure(d)
    names = {t.name for t in fig.data}
    assert {"error vs x, dithered", "error vs x, no dither"} <= names
    assert dependence_text(d) in " ".join(a.text for a in fig.layout.annotations)
    assert "plain 100 %" in dependence_text(d)
