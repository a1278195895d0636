import numpy as np
import pytest

from qsid_core import LETTER_QUANTIZER, ConfigError, Experiment, SweepConfig
from qsid_core.quantization.quantizer_demo import channel_demo, quantizer_demo


@pytest.mark.parametrize("bits", [1, 3, 8])
def test_dithered_error_is_uniform_with_variance_eps2_over_12(bits):
    x = np.random.default_rng(5).normal(0, 1, 50_000).clip(-3, 3)
    d = quantizer_demo(x, -3, 3, bits, seed=2)
    assert d.overload_dithered == 0 and d.outside_dithered == 0
    assert abs(d.var_dithered - d.eps**2 / 12) < 4 * d.var_sampling_std
    assert abs(d.corr_dithered) < 4 / np.sqrt(x.size)
    # histogram: flat at 1/eps within sampling error of each bin
    per_bin = x.size / d.hist_dithered.size
    assert np.all(np.abs(d.hist_dithered / d.uniform_density - 1) < 5 / np.sqrt(per_bin))


def test_no_dither_error_of_a_slow_signal_is_correlated_with_it():
    t = np.arange(20_000)
    x = np.sin(2 * np.pi * t / 5000)  # slowly varying
    d = quantizer_demo(x, -1, 1, 2, seed=0)
    assert abs(d.corr_plain) > 0.15 and abs(d.corr_dithered) < 0.03
    # and it is a deterministic function of the signal: same input, same error
    assert np.array_equal(quantizer_demo(x, -1, 1, 2, seed=9).error_plain, d.error_plain)


def test_window_and_shapes():
    x = np.linspace(-1, 1, 1000)
    d = quantizer_demo(x, -1, 1, 4, window=50, start=100, bins=20)
    assert d.t.tolist() == list(range(100, 150)) and d.signal.shape == d.dithered.shape == d.error_plain.shape == (50,)
    assert d.hist_edges.shape == (21,) and d.hist_edges[0] == pytest.approx(-d.eps / 2)
    np.testing.assert_allclose(d.signal - d.dithered, d.error_dithered)
    for bad in (dict(window=0), dict(bins=1), dict(start=5000)):
        with pytest.raises(ConfigError):
            quantizer_demo(x, -1, 1, 4, **bad)
    with pytest.raises(ConfigError):
        quantizer_demo([1.0, np.nan], -1, 1, 4)


def test_channel_demo_shows_overload_of_the_letter_quantizer():
    cfg = dict(system="dc-motor", bits=(2,), realizations=1, trajectories=20, steps=500, mpc=None)
    letter = channel_demo(Experiment(SweepConfig(quantizer=LETTER_QUANTIZER, **cfg)), 3, 1)
    guard = channel_demo(Experiment(SweepConfig(**cfg)), 3, 1)
    assert letter.label == guard.label == "u1"
    assert letter.overload_dithered > 0.05 and letter.corr_dithered > 0.3  # dither cannot help when overloaded
    assert guard.overload_dithered == 0 and abs(guard.corr_dithered) < 0.03
    with pytest.raises(ConfigError, match="channel"):
        channel_demo(Experiment(SweepConfig(**cfg)), 5, 2)
