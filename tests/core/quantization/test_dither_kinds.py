"""Dither kinds: subtractive, tpdf (non-subtractive triangular), rpdf (non-subtractive uniform), none.

The quantizer's error statistics per kind, the guard band covering each kind's amplitude, the fused
moments (numba and numpy) against explicit quantization, BCLS's D and its not-applicable flag, and the
TPDF result of the issue through the CLI (Boeing 747, 200 x 1000, fixed range +-20, b = 3)."""

import json

import numpy as np
import pytest

from app.cli import main
from qsid_core import ConfigError, QuantizerSpec, SweepConfig, prepare, quantize, quantized_moments, simulate
from qsid_core.identification.theorem1 import noise_covariance
from qsid_core.plant.systems import dc_motor
from qsid_core.quantization.moments import CHUNK_ROWS
from qsid_core.quantization.quantize import ERROR_VARIANCE, bcls_reason, draw_dither_units, effective_ranges


def _error_stats(dither, offset, bits=4, N=200_000, seed=3):
    """Mean and variance (in eps^2) of x~ - x for a constant signal at ``offset`` cells from a level."""
    lo, hi = -1.0, 1.0
    lo_q, eps = effective_ranges(lo, hi, bits, True, dither)
    x = np.full((N, 1), float(lo_q + eps * (7.5 + offset)))
    q = quantize(x, lo, hi, bits, dither=dither, guard=True, rng=np.random.default_rng(seed))
    e = (q.values - x) / eps
    return float(e.mean()), float(e.var()), q.overload.any()


@pytest.mark.parametrize("offset", [0.0, 0.25, 0.5])
def test_tpdf_error_has_mean_zero_and_variance_quarter_eps2_wherever_the_signal_sits(offset):
    mean, var, over = _error_stats("tpdf", offset)
    assert abs(mean) < 0.01 and var == pytest.approx(0.25, rel=0.02) and not over


def test_rpdf_error_variance_depends_on_the_signal_and_subtractive_does_not():
    v_mid = _error_stats("rpdf", 0.0)[1]  # at a level: Q(x + w) = x always, no error
    v_edge = _error_stats("rpdf", 0.5)[1]  # at a cell edge: +-eps/2 with equal odds
    assert v_mid < 0.01 and v_edge == pytest.approx(0.25, rel=0.02)
    for off in (0.0, 0.5):
        assert _error_stats("subtractive", off)[1] == pytest.approx(1 / 12, rel=0.02)


@pytest.mark.parametrize("dither", ["subtractive", "tpdf", "rpdf"])
def test_guard_band_covers_each_dithers_amplitude(dither):
    x = np.linspace(-1, 1, 20001)[:, None]  # data exactly filling the range, extremes included
    for bits in (2, 3, 6):
        q = quantize(x, -1.0, 1.0, bits, dither=dither, guard=True, rng=np.random.default_rng(bits))
        assert not q.overload.any()
    q = quantize(x, -1.0, 1.0, 2, dither=dither, guard=False, rng=np.random.default_rng(0))
    assert q.overload.any()  # without the guard band the dither pushes the extremes out


def test_tpdf_at_one_bit_gets_half_a_cell_of_guard_and_bad_kinds_are_refused():
    lo_q, eps = effective_ranges(-1.0, 1.0, 1, True, "tpdf")  # two levels: no room for a cell each side
    assert eps == pytest.approx(2.0) and lo_q == pytest.approx(-2.0)
    lo_q, eps = effective_ranges(-1.0, 1.0, 3, True, "tpdf")
    assert eps == pytest.approx(2 / 6) and lo_q == pytest.approx(-1 - 2 / 6)
    SweepConfig(bits=(1, 2), quantizer=QuantizerSpec(dither="tpdf"))  # accepted; overload measured
    with pytest.raises(ConfigError, match="dither"):
        QuantizerSpec(dither="triangular")


def _explicit(data, prep, bits, spec, seed):
    """Explicit quantization with the fused path's draws (chunk by chunk, :func:`draw_dither_units`)."""
    n, m, J, S = data.n, data.m, data.trajectories, data.steps
    rng = np.random.default_rng(seed)
    N = J * (S + 1)
    U = np.concatenate(
        [draw_dither_units(rng, (min(CHUNK_ROWS, N - s), n + m), spec.dither) for s in range(0, N, CHUNK_ROWS)]
    ).reshape(J, S + 1, n + m)
    qs = quantize(
        data.states, prep.lo[:n], prep.hi[:n], bits, dither=spec.dither, guard=spec.guard, unit_dither=U[:, :, :n]
    )
    qu = quantize(
        data.inputs, prep.lo[n:], prep.hi[n:], bits, dither=spec.dither, guard=spec.guard, unit_dither=U[:, :S, n:]
    )
    Psi = np.hstack([qs.values[:, :-1].reshape(-1, n), qu.values.reshape(-1, m)]).T
    Xp = qs.values[:, 1:].reshape(-1, n).T
    over = (qs.overload.sum() + qu.overload.sum()) / (qs.overload.size + qu.overload.size)
    return Psi @ Psi.T, Xp @ Psi.T, over


@pytest.mark.parametrize("engine", ["numpy", "auto"])
@pytest.mark.parametrize(
    "spec",
    [
        QuantizerSpec(dither="tpdf"),
        QuantizerSpec(dither="rpdf"),
        QuantizerSpec(dither="tpdf", range_mode="fixed", fixed_range=(-0.4, 0.4)),
    ],
)
def test_fused_moments_equal_explicit_quantization_for_non_subtractive_dither(spec, engine):
    data = simulate(dc_motor(), 23, 1500, seed=4)  # > one chunk, runs split across chunks
    prep = prepare(data, spec)
    bits = [1, 2, 3, 7, 12]
    fast = quantized_moments(prep, bits, spec, np.random.default_rng(9), engine=engine)
    for b, mo in zip(bits, fast):
        PP, XP, over = _explicit(data, prep, b, spec, 9)
        np.testing.assert_allclose(mo.PP, PP, rtol=1e-10, atol=1e-9 * np.abs(PP).max())
        np.testing.assert_allclose(mo.XP, XP, rtol=1e-10, atol=1e-9 * np.abs(XP).max())
        assert mo.overload_fraction == pytest.approx(over, abs=1e-15)
        np.testing.assert_allclose(mo.noise_variance, mo.eps**2 * ERROR_VARIANCE.get(spec.dither, 1 / 12))
        assert bool(mo.bcls_note) == (spec.dither == "rpdf")


def test_noise_covariance_per_dither_and_reasons():
    e = np.array([1.0, 2.0])
    np.testing.assert_allclose(np.diag(noise_covariance(e)), e**2 / 12)
    np.testing.assert_allclose(np.diag(noise_covariance(e, "tpdf")), e**2 / 4)
    np.testing.assert_allclose(np.diag(noise_covariance(e, "tpdf", 0.5)), e**2 / 4 + 0.5)
    assert bcls_reason("subtractive") == bcls_reason("tpdf") == ""
    assert "variance" in bcls_reason("rpdf") and "deterministic" in bcls_reason("none")


def _sweep_json(capsys, dither, estimator):
    code = main(
        [
            "sweep",
            "--system",
            "boeing747",
            "--bits",
            "3",
            "--range",
            "fixed",
            "--limits=-20,20",
            "--realizations",
            "1",
            "--no-mpc",
            "--dither",
            dither,
            "--estimator",
            estimator,
            "--json",
        ]
    )
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


def test_tpdf_bcls_removes_the_bias_through_the_cli_and_rpdf_is_flagged(capsys):
    ls = _sweep_json(capsys, "tpdf", "ls")
    bc = _sweep_json(capsys, "tpdf", "bcls")
    rp = _sweep_json(capsys, "rpdf", "bcls")
    (r_ls,), (r_bc,), (r_rp,) = ls["results"], bc["results"], rp["results"]
    assert r_ls["err_A"]["mean"] > 0.5 and r_bc["err_A"]["mean"] < 0.1
    assert bc["bcls"]["applicable"] is True and r_bc["assumptions"]["bcls_holds"] is True
    assert rp["bcls"]["applicable"] is False and "RPDF" in rp["bcls"]["reason"]
    assert r_rp["assumptions"]["bcls_holds"] is False
    assert rp["bcls"]["D"] == "eps^2/12 (nominal)" and bc["bcls"]["D"] == "eps^2/4"
    assert r_rp["err_A"]["mean"] > 0.5  # the nominal correction does not remove the bias


def test_bench_dither_quick_engines_agree(capsys):
    import sys
    from pathlib import Path

    bench = str(Path(__file__).resolve().parents[3] / "benchmarks")
    if bench not in sys.path:
        sys.path.insert(0, bench)
    import bench_dither

    out = bench_dither.main(["--quick"])
    assert set(out["rows"]) == {label for label, _, _ in bench_dither.ROWS}
    assert all(r["max_rel_diff_PP"] < 1e-10 for r in out["rows"].values())
    assert "RESULT " in capsys.readouterr().out
