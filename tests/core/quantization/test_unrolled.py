"""The quantize-and-accumulate kernel generated for one system size equals the generic kernel."""

from __future__ import annotations

import numpy as np
import pytest

from qsid_core.quantization import kernels, unrolled
from qsid_core.quantization.sums import Sums

needs_numba = pytest.mark.skipif(not kernels.AVAILABLE, reason=f"numba kernels unavailable: {kernels.REASON}")


def _inputs(p: int, n: int, rows: int, S1: int, nb: int, seed: int):
    rng = np.random.default_rng(seed)
    y = rng.uniform(-0.6, 0.6, (rows, p))  # beyond +-1/2: some entries overload
    u = rng.uniform(-0.5, 0.5, (rows, p))
    bits = np.arange(1, nb + 1)
    scale = np.repeat((2.0**bits - 2.0)[:, None], p, axis=1)
    half = np.repeat((2.0 ** (bits - 1))[:, None], p, axis=1)
    runs = -(-(rows + 3 * S1) // S1)
    return y, u, scale, half, runs


def _run(fn, y, u, sub, quant, scale, half, row0, S1, n, runs):
    out = Sums.zeros(scale.shape[0], scale.shape[1], n, runs).arrays()
    for start in range(0, len(y), 700):  # several calls: the previous row is carried between them
        fn(y[start : start + 700], u[start : start + 700], sub, quant, scale, half, row0 + start, S1, *out)
    return out


@needs_numba
@pytest.mark.parametrize(("p", "n"), [(2, 1), (5, 3), (6, 4), (4, 4), (8, 5)])
@pytest.mark.parametrize("sub", [1.0, 0.0])
@pytest.mark.parametrize("row0", [0, 613])
def test_the_generated_kernel_computes_the_generic_sums(p, n, sub, row0):
    y, u, scale, half, runs = _inputs(p, n, rows=2100, S1=301, nb=4, seed=p * 10 + n)
    quant = np.ones(p, dtype=np.bool_)
    quant[-1] = False  # one channel recorded exactly
    fn = unrolled.kernel(p, n)
    assert fn is not None, unrolled.NOT_USED
    a = _run(kernels._accumulate_chunk_nb, y, u, sub, quant, scale, half, row0, 301, n, runs)
    b = _run(fn, y, u, sub, quant, scale, half, row0, 301, n, runs)
    for x, z in zip(a[:3], b[:3]):  # sums: the order of additions differs
        np.testing.assert_allclose(z, x, rtol=1e-12, atol=1e-12 * np.abs(x).max())
    for x, z in zip(a[3:], b[3:]):  # overload counts, carried rows, run ends: the same numbers
        np.testing.assert_array_equal(z, x)
    assert a[3].sum() > 0


@needs_numba
def test_accumulate_chunk_runs_the_generated_kernel_it_is_given():
    p, n = 5, 3
    y, u, scale, half, runs = _inputs(p, n, rows=900, S1=300, nb=2, seed=1)
    out = Sums.zeros(2, p, n, runs).arrays()
    kernels.accumulate_chunk(y, u, scale, half, 0, 300, *out, kernel=unrolled.kernel(p, n))
    assert unrolled.kernel(p, n) is not None and (p, n) not in unrolled.NOT_USED
    ref = _run(kernels._accumulate_chunk_nb, y, u, 1.0, np.ones(p, dtype=np.bool_), scale, half, 0, 300, n, runs)
    np.testing.assert_allclose(out[0], ref[0], rtol=1e-12)


@needs_numba
def test_more_channels_than_the_limit_use_the_generic_kernel_and_say_why():
    p = unrolled.MAX_CHANNELS + 1
    assert unrolled.kernel(p, 3) is None
    assert "not specialised" in unrolled.NOT_USED[(p, 3)]


@needs_numba
def test_an_unwritable_cache_falls_back_to_the_generic_kernel_with_the_reason(monkeypatch, tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    monkeypatch.setattr(unrolled, "_LOADED", {})
    monkeypatch.setattr(unrolled, "NOT_USED", {})
    monkeypatch.setattr(kernels, "cache_dir", lambda: str(blocker / "cache"))
    assert unrolled.kernel(5, 3) is None
    assert "a-file" in unrolled.NOT_USED[(5, 3)]


def test_the_generated_file_is_rewritten_only_when_its_text_changes(tmp_path):
    path = tmp_path / "gen" / "m.py"
    unrolled._write(path, "x = 1\n")
    first = path.stat().st_mtime_ns
    unrolled._write(path, "x = 1\n")
    assert path.stat().st_mtime_ns == first
    unrolled._write(path, "x = 2\n")
    assert path.read_text() == "x = 2\n"
    assert [q.name for q in path.parent.iterdir()] == ["m.py"]  # no temporary file left


@pytest.mark.parametrize(("p", "n"), [(3, 0), (3, 4), (0, 0)])
def test_impossible_sizes_are_refused(p, n):
    with pytest.raises(ValueError, match="1 <= n <= p"):
        unrolled.source(p, n)


def test_the_source_unrolls_every_sum_once():
    text = unrolled.source(5, 3)
    assert text.count("+= v") == 5 + 15  # plain sums and the upper triangle of M
    assert text.count("c0_0 +=") == 1 and text.count(" * x") == 15  # C: 5 x 3
    compile(text, "generated", "exec")


@needs_numba
def test_quantized_moments_use_the_generated_kernel(monkeypatch):
    from qsid_core import QuantizerSpec, prepare, quantized_moments, simulate
    from qsid_core.plant.systems import dc_motor

    used = []
    real = unrolled.kernel

    def spy(p, n):
        used.append((p, n))
        return real(p, n)

    monkeypatch.setattr(unrolled, "kernel", spy)
    spec = QuantizerSpec()
    prep = prepare(simulate(dc_motor(), 3, 50, seed=1), spec)
    quantized_moments(prep, [3, 4], spec, np.random.default_rng(0), engine="numba")
    assert used == [(5, 3)]
