"""Dictionaries and EDMD from quantized data: the exact de-biasing checked against independent computations."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import bernoulli

from qsid_core.errors import ConfigError, IdentificationError
from qsid_core.identification import (
    bernoulli_shifted,
    edmd,
    exact_lifted_moments,
    identify,
    least_squares,
    lifted_error,
    parse_lifting,
    quantized_lifted_moments,
)
from qsid_core.plant import Dataset, get_nonlinear, get_system, simulate, simulate_nonlinear
from qsid_core.quantization import (
    Moments,
    QuantizerSpec,
    data_ranges,
    draw_dither_units,
    effective_ranges,
    quantize,
)


def test_poly_dictionary_holds_every_monomial_up_to_the_degree_constant_and_state_first():
    lf = parse_lifting("poly:3", 2)
    assert lf.L == math.comb(5, 3) == 10 and lf.state_rows == (1, 2)
    x = np.array([[0.5, -2.0]])
    z = lf.lift(x)[0]
    want = sorted(x[0, 0] ** a * x[0, 1] ** b for a in range(4) for b in range(4) if a + b <= 3)
    assert sorted(z) == pytest.approx(want) and z[0] == 1.0
    np.testing.assert_array_equal(lf.C @ z, x[0])


def test_rbf_dictionary_is_the_state_plus_k_radial_functions_with_seeded_centres():
    a, b = parse_lifting("rbf:5", 2, seed=1), parse_lifting("rbf:5", 2, seed=1)
    np.testing.assert_array_equal(a.centres, b.centres)
    x = np.array([[0.3, 0.1]])
    z = a.lift(x)[0]
    r = np.linalg.norm(x[0] - a.centres[2])
    assert a.L == 7 and z[2 + 2] == pytest.approx(r**2 * np.log(r))
    g = parse_lifting("rbf:5:gauss", 2).lift(x)[0]
    assert np.all((g[2:] > 0) & (g[2:] <= 1))


@pytest.mark.parametrize(
    ("spec", "match"),
    [("poly:0", "degree"), ("rbf:0", "K must be"), ("cheb:3", "unknown dictionary"), ("poly:x", "whole number")],
)
def test_bad_dictionaries_are_one_line_config_errors_naming_the_lifting(spec, match):
    with pytest.raises(ConfigError, match=match) as e:
        parse_lifting(spec, 2)
    assert str(e.value).startswith("lifting ") and "\n" not in str(e.value)


def test_too_few_samples_for_the_features_is_an_identification_error():
    s = get_nonlinear("duffing")
    d = simulate_nonlinear(s, 1, 5, seed=0)
    lf = parse_lifting("poly:3", 2)
    with pytest.raises(IdentificationError, match="samples: 5 samples cannot fit 11 unknowns"):
        edmd(exact_lifted_moments(d, lf), lf.C)


def test_shifted_bernoulli_powers_are_unbiased_by_exact_integration_over_the_dither():
    # E over e ~ U[-eps/2, eps/2] of sum_i c[k, i] (x + e)^i eps^(k - i), by 40-point Gauss-Legendre (exact here)
    c = bernoulli_shifted(8)
    np.testing.assert_allclose(c[2, :3], [-1 / 12, 0, 1])
    nodes, weights = np.polynomial.legendre.leggauss(40)
    for x, eps in ((0.37, 0.5), (-1.3, 0.25), (2.0, 1.0)):
        e = nodes * eps / 2
        for k in range(9):
            vals = sum(c[k, i] * (x + e) ** i * eps ** (k - i) for i in range(k + 1))
            assert 0.5 * float(weights @ vals) == pytest.approx(x**k, rel=1e-12, abs=1e-12)


def _brute_force(data, lf, b, spec, seed):
    """The lifted moments sample by sample in plain numpy, Bernoulli polynomials from scipy's numbers."""
    n, m = data.n, data.m
    lo, hi = data_ranges(data.states, data.inputs, spec)
    W = draw_dither_units(np.random.default_rng(seed), (data.trajectories, data.steps + 1, n + m), spec.dither)
    xq = quantize(data.states, lo[:n], hi[:n], b, guard=True, unit_dither=W[..., :n])
    uq = quantize(data.inputs, lo[n:], hi[n:], b, guard=True, unit_dither=W[:, :-1, n:])
    ex, eu = xq.eps, uq.eps
    Bn = bernoulli(12)

    def unb(v, e, k):  # e^k B_k(v/e + 1/2) from the Bernoulli numbers: B_k(s) = sum_j C(k, j) B_j s^(k-j)
        s = v / e + 0.5
        return e**k * sum(math.comb(k, j) * Bn[j] * s ** (k - j) for j in range(k + 1))

    def mono(x, alpha, unbiased):
        return np.prod([unb(x[c], ex[c], a) if unbiased else x[c] ** a for c, a in enumerate(alpha)])

    E = lf.exponents
    L = E.shape[0]
    out = {}
    for unbiased in (False, True):
        PP = np.zeros((L + m, L + m))
        XP = np.zeros((L, L + m))
        for r in range(data.trajectories):
            for t in range(data.steps):
                x, xn, u = xq.values[r, t], xq.values[r, t + 1], uq.values[r, t]
                f = [mono(x, E[i], unbiased) for i in range(L)]
                fn = [mono(xn, E[i], unbiased) for i in range(L)]
                for i in range(L):
                    for j in range(L):
                        PP[i, j] += mono(x, E[i] + E[j], unbiased)  # one sample: one monomial, summed exponents
                        XP[i, j] += fn[i] * f[j]  # two samples: independent dither, the product factors
                    for a in range(m):
                        PP[i, L + a] += f[i] * u[a]
                        PP[L + a, i] += f[i] * u[a]
                        XP[i, L + a] += fn[i] * u[a]
                for a in range(m):
                    for c in range(m):
                        PP[L + a, L + c] += u[a] * u[c] - (unbiased and a == c) * eu[a] ** 2 / 12
        out[unbiased] = (PP, XP)
    return out


@pytest.mark.parametrize("case", ["van-der-pol poly:2", "3 states 2 inputs poly:3"])
def test_engine_moments_equal_an_independent_brute_force_loop_over_samples(case):
    if case.startswith("van"):
        d = simulate_nonlinear(get_nonlinear("van-der-pol"), 3, 6, seed=2)
        lf = parse_lifting("poly:2", 2)
    else:
        rng = np.random.default_rng(8)
        d = Dataset(rng.uniform(-2, 2, (2, 5, 3)), rng.uniform(-1, 1, (2, 4, 2)))
        lf = parse_lifting("poly:3", 3)
    spec = QuantizerSpec()
    mom = quantized_lifted_moments(d, lf, [3], spec, seed=5)[0]
    want = _brute_force(d, lf, 3, spec, 5)
    np.testing.assert_allclose(mom.PP, want[False][0], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(mom.XP, want[False][1], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(mom.PPu, want[True][0], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(mom.XPu, want[True][1], rtol=1e-9, atol=1e-9)


def test_unquantized_moments_from_the_kernel_equal_the_lifted_products():
    d = simulate_nonlinear(get_nonlinear("duffing"), 7, 40, seed=4)
    lf = parse_lifting("poly:3", 2)
    Z = lf.lift(d.states)
    Phi = np.concatenate([Z[:, :-1], d.inputs], axis=2).reshape(-1, lf.L + 1)
    Zp = Z[:, 1:].reshape(-1, lf.L)
    mom = exact_lifted_moments(d, lf)
    assert mom.T == 7 * 40 and not mom.eps.any()
    np.testing.assert_allclose(mom.PP, Phi.T @ Phi, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(mom.XP, Zp.T @ Phi, rtol=1e-12, atol=1e-9)


@pytest.mark.slow
def test_de_biased_moments_average_to_the_unquantized_ones_and_ls_moments_do_not():
    s = get_nonlinear("duffing")
    d = simulate_nonlinear(s, 4, 8, seed=0)
    lf = parse_lifting("poly:2", 2)
    exact = exact_lifted_moments(d, lf)
    draws = [quantized_lifted_moments(d, lf, [2], seed=k)[0] for k in range(3000)]
    for name in ("PP", "XP"):
        plain = np.array([getattr(m, name) for m in draws])
        unb = np.array([getattr(m, name + "u") for m in draws])
        se = unb.std(axis=0) / np.sqrt(len(draws)) + 1e-9
        z_unb = np.abs(unb.mean(axis=0) - getattr(exact, name)) / se
        z_ls = np.abs(plain.mean(axis=0) - getattr(exact, name)) / (plain.std(axis=0) / np.sqrt(len(draws)) + 1e-9)
        assert z_unb.max() < 5.0  # unbiased: every entry within 5 standard errors
        if name == "PP":
            assert z_ls.max() > 20.0  # LS's Gram is biased (x~^2 has mean x^2 + eps^2/12)


def test_identity_lifting_is_exactly_the_letters_least_squares_and_bcls():
    sysm = get_system("dc-motor")
    d = simulate(sysm, 20, 50, seed=1)
    lf = parse_lifting("identity", sysm.n)
    Psi, Xp = d.matrices()
    A, B = least_squares(Psi @ Psi.T, Xp @ Psi.T, sysm.n)
    ex = edmd(exact_lifted_moments(d, lf), lf.C)
    np.testing.assert_allclose(ex.A, A, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(ex.B, B, rtol=1e-12, atol=1e-12)
    for b in (3, 6):
        mom = quantized_lifted_moments(d, lf, [b], seed=4)[0]
        lin = Moments(PP=mom.PP, XP=mom.XP, T=mom.T, eps=mom.eps)
        for est in ("ls", "bcls"):
            got, want = edmd(mom, lf.C, est), identify(lin, est)
            assert got.estimator == want.estimator
            np.testing.assert_allclose(got.A, want.A, rtol=1e-9, atol=1e-11)
            np.testing.assert_allclose(got.B, want.B, rtol=1e-9, atol=1e-11)


def test_rbf_and_non_subtractive_dither_say_there_is_no_exact_correction():
    s = get_nonlinear("van-der-pol")
    d = simulate_nonlinear(s, 200, 50, seed=0)
    rbf = parse_lifting("rbf:8", 2)
    mom = quantized_lifted_moments(d, rbf, [4], seed=0)[0]
    k = edmd(mom, rbf.C, "bcls")
    assert k.estimator == "ls" and k.fallback and "no exact correction" in k.note
    poly = parse_lifting("poly:3", 2)
    ref = edmd(exact_lifted_moments(d, poly), poly.C)
    sub = edmd(quantized_lifted_moments(d, poly, [4], seed=0)[0], poly.C, "bcls")
    tp = quantized_lifted_moments(d, poly, [4], QuantizerSpec(dither="tpdf"), seed=0)[0]
    tk = edmd(tp, poly.C, "bcls")
    assert "no exact correction with tpdf" in tk.note
    # the nominal correction leaves a bias with TPDF dither many times the subtractive one's error
    assert lifted_error(tk, ref)[0] > 5 * lifted_error(sub, ref)[0]


@pytest.mark.parametrize(
    ("runs", "steps", "n", "m", "spec_text", "dither"),
    [
        (40, 30, 2, 1, "poly:3", "subtractive"),  # several runs per block of the kernel
        (5, 256, 2, 1, "poly:2", "subtractive"),  # a run of exactly one block: it ends on the block's last sample
        (2, 600, 2, 1, "poly:3", "tpdf"),  # runs over several blocks, which share their boundary samples
        (300, 1, 2, 1, "identity", "subtractive"),  # one regressor per run
        (7, 127, 2, 1, "poly:4", "none"),  # two runs per block, no dither
        (9, 50, 3, 2, "poly:2", "subtractive"),  # three states, two inputs
        (20, 13, 1, 1, "poly:5", "rpdf"),  # one state
    ],
)
def test_the_compiled_kernel_equals_the_whole_array_sums(runs, steps, n, m, spec_text, dither):
    from qsid_core.identification import edmd_kernel
    from qsid_core.identification.edmd_plan import plan_for

    rng = np.random.default_rng(n + 10 * m)
    d = Dataset(rng.uniform(-2, 2, (runs, steps + 1, n)), rng.uniform(-1, 1, (runs, steps, m)))
    spec = QuantizerSpec(dither=dither, guard=False)  # no guard band: some entries overload
    plan = plan_for(parse_lifting(spec_text, n).exponents, m)
    lo, hi = data_ranges(d.states, d.inputs, spec)
    bits = [1, 2, 5, 12]
    ranges = [effective_ranges(lo, hi, b, spec.guard, spec.dither) for b in bits]
    lo_q, eps = np.array([r[0] for r in ranges]), np.array([r[1] for r in ranges])
    eps[2, -1] = 0.0  # one channel recorded exactly at one word length
    W = draw_dither_units(np.random.default_rng(3), (runs, steps + 1, n + m), dither)
    W = np.zeros((runs, steps + 1, n + m)) if W is None else W
    args = (d.states, d.inputs, W, lo_q, eps, 2.0 ** np.array(bits, dtype=float), float(dither == "subtractive"))
    fast = edmd_kernel.lifted_sums(*args, plan)
    slow = edmd_kernel.lifted_sums_numpy(*args, plan)
    assert edmd_kernel.AVAILABLE
    for a, b in zip(fast[:4], slow[:4], strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-9 * np.abs(b).max())
    np.testing.assert_array_equal(fast[4], slow[4])
    assert fast[4].max() > 0 or dither == "none"  # the overload count is exercised (dither crosses the range)
