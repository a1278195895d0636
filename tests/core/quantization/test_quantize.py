import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from qsid_core import ConfigError, QuantizerSpec, quantize
from qsid_core.quantization.quantize import cell_width, data_ranges, effective_ranges


@pytest.mark.parametrize("bits", [1, 2, 3, 8, 12, 24])
def test_exactly_2_to_the_b_levels(bits):
    lo, hi = -1.5, 2.5
    x = np.linspace(lo - 1, hi + 1, 200_001)  # includes x = hi exactly and overload on both sides
    x = np.concatenate([x, [lo, hi]])
    q = quantize(x, lo, hi, bits, dither="none", guard=False)  # the letter's quantizer
    levels = np.unique(q.values)
    eps = (hi - lo) / 2**bits
    expected_all = lo + eps / 2 + eps * np.arange(2**bits)
    if bits <= 12:
        assert levels.size == 2**bits
        np.testing.assert_allclose(levels, expected_all, atol=1e-12)
    else:  # fewer samples than levels: every output is still one of the 2**b levels
        k = (levels - lo - eps / 2) / eps
        np.testing.assert_allclose(k, np.round(k), atol=1e-6)
        assert k.min() >= 0 and k.max() <= 2**bits - 1
    # x = hi maps to the top level, not to a 2^b+1-th one
    assert quantize(np.array([hi]), lo, hi, bits, dither="none", guard=False).values[0] == pytest.approx(
        expected_all[-1]
    )


@pytest.mark.parametrize("dither", ["none", "subtractive"])
@pytest.mark.parametrize("guard", [False, True])
def test_in_range_error_within_half_cell(dither, guard):
    rng = np.random.default_rng(0)
    x = rng.uniform(-2, 3, 50_000)
    for bits in (1, 3, 6, 10):
        q = quantize(x, -2, 3, bits, dither=dither, guard=guard, rng=rng)
        err = x - q.values
        inside = ~q.overload
        assert np.all(np.abs(err[inside]) <= q.eps / 2 * (1 + 1e-12))
        if guard:
            assert not q.overload.any()


def test_guard_band_geometry():
    lo_q, eps = effective_ranges(np.array([0.0]), np.array([1.0]), 3, True)
    assert eps[0] == pytest.approx(1 / 7) and lo_q[0] == pytest.approx(-1 / 14)
    assert cell_width(0.0, 1.0, 3, guard=False) == pytest.approx(1 / 8)
    assert cell_width(0.0, 1.0, 3) == pytest.approx(1 / 7)  # guard band is the default


def test_guard_is_default_and_letter_preset_has_none():
    from qsid_core import LETTER_QUANTIZER, SweepConfig

    assert QuantizerSpec().guard is True and LETTER_QUANTIZER.guard is False
    assert LETTER_QUANTIZER.range_mode == "per-channel" and LETTER_QUANTIZER.dither == "subtractive"
    letter = SweepConfig.letter("boeing747")
    assert letter.quantizer == LETTER_QUANTIZER and letter.input_amplitude == 1.0
    assert (letter.trajectories, letter.steps, letter.realizations, letter.bits) == (200, 1000, 50, tuple(range(1, 17)))
    assert SweepConfig.letter(bits="2:4").bits == (2, 3, 4)
    with pytest.raises(ConfigError, match="guard"):
        QuantizerSpec(guard="yes")


def test_fixed_range_one_pair_or_one_per_channel():
    states = np.zeros((1, 3, 2))
    inputs = np.zeros((1, 2, 1))
    lo, hi = data_ranges(states, inputs, QuantizerSpec(range_mode="fixed", fixed_range=(-20, 20)))
    np.testing.assert_array_equal(lo, [-20, -20, -20]) and np.testing.assert_array_equal(hi, [20, 20, 20])
    spec = QuantizerSpec(range_mode="fixed", fixed_range=[(-1, 1), (-2, 2), (0, 5)])
    lo, hi = data_ranges(states, inputs, spec)
    np.testing.assert_array_equal(lo, [-1, -2, 0]) and np.testing.assert_array_equal(hi, [1, 2, 5])
    with pytest.raises(ConfigError, match="one per channel"):
        data_ranges(states, inputs, QuantizerSpec(range_mode="fixed", fixed_range=[(0, 1), (0, 1)]))


@settings(max_examples=25, deadline=None)
@given(
    bits=st.integers(1, 12),
    lo=st.floats(-100, 100),
    width=st.floats(0.01, 100),
    seed=st.integers(0, 2**32 - 1),
    shape=st.sampled_from(["ramp", "sine", "square", "uniform"]),
)
def test_subtractive_dither_error_is_uniform_and_signal_independent(bits, lo, width, seed, shape):
    hi = lo + width
    rng = np.random.default_rng(seed)
    N = 40_000
    t = np.linspace(0, 1, N)
    u = {
        "ramp": t,
        "sine": 0.5 + 0.5 * np.sin(40 * t),
        "square": (np.sin(30 * t) > 0) * 1.0,
        "uniform": rng.uniform(0, 1, N),
    }[shape]
    x = lo + width * (0.02 + 0.96 * u)
    q = quantize(x, lo, hi, bits, dither="subtractive", guard=True, rng=rng)
    e = (x - q.values) / q.eps  # normalised error, should be U[-1/2, 1/2]
    assert not q.overload.any()
    assert abs(e.mean()) < 5 * np.sqrt(1 / 12 / N)
    assert e.var() == pytest.approx(1 / 12, rel=0.05)
    if np.std(x) > 0:
        assert abs(np.corrcoef(e, x)[0, 1]) < 5 / np.sqrt(N)


def test_without_dither_error_depends_on_signal():
    x = np.linspace(0.0, 0.1, 10_000)  # a slow ramp inside one coarse cell
    q = quantize(x, 0, 1, 3, dither="none", guard=False)
    e = x - q.values
    assert abs(np.corrcoef(e, x)[0, 1]) > 0.9


def test_overload_reported():
    x = np.array([-1.0, 0.5, 2.0])
    q = quantize(x, 0, 1, 4, dither="none")
    np.testing.assert_array_equal(q.overload, [True, False, True])
    assert q.overload_fraction == pytest.approx(2 / 3)


def test_data_ranges_modes():
    states = np.array([[[0.0, -2.0], [1.0, 2.0]]])
    inputs = np.array([[[5.0]]])
    lo, hi = data_ranges(states, inputs, QuantizerSpec())
    np.testing.assert_allclose(lo[:2], [0, -2])
    np.testing.assert_allclose(hi[:2], [1, 2])
    assert hi[2] > lo[2]  # constant channel gets a tiny range
    lo, hi = data_ranges(states, inputs, QuantizerSpec(range_mode="shared"))
    assert np.all(lo == -2) and np.all(hi == 5)
    lo, hi = data_ranges(states, inputs, QuantizerSpec(range_mode="fixed", fixed_range=(-10, 10)))
    assert np.all(lo == -10) and np.all(hi == 10)
    with pytest.raises(ConfigError, match="one pair or one per channel"):
        data_ranges(states, inputs, QuantizerSpec(range_mode="fixed", fixed_range=[(0, 1), (0, 1)]))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(dither="triangular"), "dither must be one of"),
        (dict(range_mode="auto"), "range must be one of"),
        (dict(range_mode="fixed"), "needs fixed_range"),
        (dict(range_mode="fixed", fixed_range=(1, 0)), "lo < hi"),
    ],
)
def test_bad_quantizer_specs(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        QuantizerSpec(**kwargs)


@pytest.mark.parametrize("bits", [0, 33, 2.5, "4", True])
def test_bad_bits(bits):
    with pytest.raises(ConfigError, match="bits"):
        quantize(np.zeros(3), 0, 1, bits)


def test_bad_range():
    with pytest.raises(ConfigError, match="hi > lo"):
        quantize(np.zeros(3), 1, 1, 4)
