import numpy as np
import pytest

from qsid_core import QuantizerSpec, prepare, quantize, quantized_moments, simulate
from qsid_core.systems import boeing747, dc_motor


def _explicit(data, prep, bits, spec, seed):
    """Quantize with the reference quantizer and the same unit draws, then form Psi explicitly."""
    n, m = data.n, data.m
    J, S = data.trajectories, data.steps
    U = np.random.default_rng(seed).uniform(-0.5, 0.5, size=(J * (S + 1), n + m)).reshape(J, S + 1, n + m)
    sub = spec.dither == "subtractive"
    qs = quantize(data.states, prep.lo[:n], prep.hi[:n], bits, dither=spec.dither, guard=spec.guard,
                  unit_dither=U[:, :, :n] if sub else None)
    qu = quantize(data.inputs, prep.lo[n:], prep.hi[n:], bits, dither=spec.dither, guard=spec.guard,
                  unit_dither=U[:, :S, n:] if sub else None)
    Psi = np.hstack([qs.values[:, :-1].reshape(-1, n), qu.values.reshape(-1, m)]).T
    Xp = qs.values[:, 1:].reshape(-1, n).T
    over = (qs.overload.sum() + qu.overload.sum()) / (qs.overload.size + qu.overload.size)
    return Psi @ Psi.T, Xp @ Psi.T, over


@pytest.mark.parametrize("system", [dc_motor, boeing747])
@pytest.mark.parametrize(
    "spec",
    [QuantizerSpec(), QuantizerSpec(range_mode="shared", guard=True), QuantizerSpec(dither="none"),
     QuantizerSpec(range_mode="fixed", fixed_range=(-3, 3))],
)
def test_fast_moments_equal_explicit_quantization(system, spec):
    data = simulate(system(), 23, 1500, seed=4)  # > one chunk, runs split across chunks
    prep = prepare(data, spec)
    bits = [1, 3, 7, 12]
    fast = quantized_moments(prep, bits, spec, np.random.default_rng(9))
    for b, mo in zip(bits, fast):
        PP, XP, over = _explicit(data, prep, b, spec, 9)
        np.testing.assert_allclose(mo.PP, PP, rtol=1e-11, atol=1e-9 * np.abs(PP).max())
        np.testing.assert_allclose(mo.XP, XP, rtol=1e-11, atol=1e-9 * np.abs(XP).max())
        assert mo.overload_fraction == pytest.approx(over, abs=1e-15)
        assert mo.T == data.T


def test_common_random_numbers_do_not_depend_on_requested_bits():
    data = simulate(dc_motor(), 5, 400, seed=1)
    spec = QuantizerSpec()
    prep = prepare(data, spec)
    a = quantized_moments(prep, [4], spec, np.random.default_rng(2))[0]
    b = quantized_moments(prep, [2, 4, 9], spec, np.random.default_rng(2))[1]
    np.testing.assert_array_equal(a.PP, b.PP)


def test_exact_moments_are_unquantized_gram():
    data = simulate(dc_motor(), 4, 100, seed=0)
    prep = prepare(data, QuantizerSpec())
    Psi, Xp = data.matrices()
    np.testing.assert_allclose(prep.exact.PP, Psi @ Psi.T)
    np.testing.assert_allclose(prep.exact.XP, Xp @ Psi.T)


def test_subtractive_dither_needs_rng():
    data = simulate(dc_motor(), 2, 50, seed=0)
    spec = QuantizerSpec()
    with pytest.raises(ValueError, match="random generator"):
        quantized_moments(prepare(data, spec), [4], spec, None)
