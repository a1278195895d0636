import numpy as np
import pytest

from qsid_core import ConfigError, QuantizerSpec, prepare, quantize, quantized_moments, simulate
from qsid_core.plant.systems import boeing747, dc_motor


def _explicit(data, prep, bits, spec, seed):
    """Quantize with the reference quantizer and the same unit draws, then form Psi explicitly."""
    n, m = data.n, data.m
    J, S = data.trajectories, data.steps
    U = np.random.default_rng(seed).uniform(-0.5, 0.5, size=(J * (S + 1), n + m)).reshape(J, S + 1, n + m)
    sub = spec.dither == "subtractive"
    qs = quantize(
        data.states,
        prep.lo[:n],
        prep.hi[:n],
        bits,
        dither=spec.dither,
        guard=spec.guard,
        unit_dither=U[:, :, :n] if sub else None,
    )
    qu = quantize(
        data.inputs,
        prep.lo[n:],
        prep.hi[n:],
        bits,
        dither=spec.dither,
        guard=spec.guard,
        unit_dither=U[:, :S, n:] if sub else None,
    )
    Psi = np.hstack([qs.values[:, :-1].reshape(-1, n), qu.values.reshape(-1, m)]).T
    Xp = qs.values[:, 1:].reshape(-1, n).T
    over = (qs.overload.sum() + qu.overload.sum()) / (qs.overload.size + qu.overload.size)
    return Psi @ Psi.T, Xp @ Psi.T, over


@pytest.mark.parametrize("system", [dc_motor, boeing747])
@pytest.mark.parametrize(
    "spec",
    [
        QuantizerSpec(),
        QuantizerSpec(range_mode="shared", guard=True),
        QuantizerSpec(dither="none"),
        QuantizerSpec(range_mode="fixed", fixed_range=(-3, 3)),
    ],
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


kernels = pytest.importorskip("qsid_core.quantization.kernels")
needs_numba = pytest.mark.skipif(not kernels.AVAILABLE, reason=f"numba kernels unavailable: {kernels.REASON}")


@needs_numba
@pytest.mark.parametrize(
    "spec",
    [
        QuantizerSpec(),
        QuantizerSpec(range_mode="shared", guard=True),
        QuantizerSpec(dither="none"),
        QuantizerSpec(range_mode="fixed", fixed_range=(-0.5, 0.5)),
    ],  # the last one overloads
)
@pytest.mark.parametrize("chunk", [None, 777])  # 777 rows: chunk and kernel-block edges inside runs
def test_numba_kernel_equals_numpy_reference(spec, chunk, monkeypatch):
    import qsid_core.quantization.moments as moments

    if chunk:
        monkeypatch.setattr(moments, "CHUNK_ROWS", chunk)
    data = simulate(boeing747(), 7, 450, seed=3)
    prep = prepare(data, spec)
    bits = [1, 2, 5, 11, 16]
    a = quantized_moments(prep, bits, spec, np.random.default_rng(4), engine="numba")
    b = quantized_moments(prep, bits, spec, np.random.default_rng(4), engine="numpy")
    for x, y in zip(a, b):
        assert np.abs(x.PP - y.PP).max() <= 1e-12 * np.abs(y.PP).max()
        assert np.abs(x.XP - y.XP).max() <= 1e-12 * np.abs(y.XP).max()
        assert x.overload_fraction == y.overload_fraction
        np.testing.assert_array_equal(x.eps, y.eps)
    if spec.range_mode == "fixed":
        assert max(x.overload_fraction for x in a) > 0  # the overload count was exercised


def test_unknown_or_unavailable_engine_is_a_config_error(monkeypatch):
    from qsid_core import ConfigError

    data = simulate(dc_motor(), 2, 50, seed=0)
    spec = QuantizerSpec()
    prep = prepare(data, spec)
    with pytest.raises(ConfigError, match="engine"):
        quantized_moments(prep, [4], spec, np.random.default_rng(0), engine="fortran")
    monkeypatch.setattr(kernels, "AVAILABLE", False)
    monkeypatch.setattr(kernels, "REASON", "numba is not installed")
    with pytest.raises(ConfigError, match="numba is not installed"):
        quantized_moments(prep, [4], spec, np.random.default_rng(0), engine="numba")
    # auto falls back to numpy
    assert quantized_moments(prep, [4], spec, np.random.default_rng(0))[0].T == data.T


def test_cache_dir_falls_back_to_a_user_cache_when_the_package_is_read_only(monkeypatch, tmp_path):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(kernels.os, "access", lambda path, mode: False)
    assert kernels.cache_dir() == str(tmp_path / "qsid" / "numba")
    monkeypatch.setenv("NUMBA_CACHE_DIR", "/somewhere")
    assert kernels.cache_dir() == "/somewhere"


def test_numba_can_be_switched_off_with_a_reason():
    import subprocess
    import sys

    from conftest import ROOT

    env = {**__import__("os").environ, "QSID_NO_NUMBA": "1"}
    out = subprocess.run(
        [sys.executable, "-c", "from qsid_core.quantization import kernels; print(kernels.AVAILABLE, kernels.REASON)"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.stdout.strip() == "False numba disabled by QSID_NO_NUMBA"


def test_unit_dither_is_numpys_uniform_bit_for_bit_and_leaves_the_stream_where_it_did():
    from qsid_core.quantization.quantize import draw_unit_dither

    for seed in (0, 1, 12345):
        a, b = np.random.default_rng(seed), np.random.default_rng(seed)
        for shape in ((16384, 5), (7, 3), (1, 1)):
            assert np.array_equal(draw_unit_dither(a, shape), b.uniform(-0.5, 0.5, size=shape))
        assert a.random() == b.random()  # the same number of draws was consumed


@pytest.mark.parametrize("engine", ["numba", "numpy"])
@pytest.mark.parametrize(
    "spec",
    [
        QuantizerSpec(),
        QuantizerSpec(dither="tpdf", guard=True),  # two draws per entry: a shorter chunk is not a prefix of a longer
        QuantizerSpec(dither="rpdf", range_mode="shared"),
        QuantizerSpec(dither="none"),
    ],
)
def test_nested_runs_give_each_word_length_its_own_prefix_bit_for_bit(engine, spec, monkeypatch):
    import qsid_core.quantization.moments as moments

    if engine == "numba" and not kernels.AVAILABLE:
        pytest.skip(f"numba kernels unavailable: {kernels.REASON}")
    monkeypatch.setattr(moments, "CHUNK_ROWS", 700)  # runs of 41 rows: many chunks, prefixes ending inside them
    data = simulate(boeing747(), 60, 40, seed=5)
    prep = prepare(data, spec)
    bits, runs = [1, 3, 6, 9, 14], [60, 31, 17, 60, 1]
    together = quantized_moments(prep, bits, spec, np.random.default_rng(8), engine=engine, runs=runs)
    for b, r, got in zip(bits, runs, together):
        alone_prep = prepare(type(data)(data.states[:r], data.inputs[:r], data.seed, 1.0), _fixed_to(prep, spec))
        alone = quantized_moments(alone_prep, [b], spec, np.random.default_rng(8), engine=engine)[0]
        for field in ("PP", "XP", "eps", "D"):
            np.testing.assert_array_equal(getattr(got, field), getattr(alone, field))
        assert (got.T, got.overload_fraction) == (alone.T, alone.overload_fraction)
    with pytest.raises(ConfigError, match="runs"):
        quantized_moments(prep, bits, spec, np.random.default_rng(8), runs=[61, 1, 1, 1, 1])


def _fixed_to(prep, spec):
    """``spec`` with its range fixed to ``prep``'s, so a prefix of the data is normalised alike."""
    return QuantizerSpec(
        dither=spec.dither, guard=spec.guard, range_mode="fixed", fixed_range=tuple(zip(prep.lo, prep.hi))
    )
