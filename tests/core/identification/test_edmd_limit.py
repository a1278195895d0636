"""The large-data limit of LS quantized EDMD, checked against independent computations."""

from __future__ import annotations

import numpy as np
import pytest

from qsid_core.identification import (
    LARGE_DATA_HYPOTHESES,
    edmd,
    error_moments,
    exact_lifted_moments,
    large_data_limit,
    lifted_error,
    parse_lifting,
    quantized_lifted_moments,
)
from qsid_core.plant import Dataset, get_nonlinear, simulate_nonlinear
from qsid_core.quantization import QuantizerSpec, data_ranges, effective_ranges


def _data(runs: int = 6, steps: int = 5, n: int = 2, m: int = 1, seed: int = 3) -> Dataset:
    rng = np.random.default_rng(seed)
    return Dataset(rng.uniform(-2, 2, (runs, steps + 1, n)), rng.uniform(-1, 1, (runs, steps, m)))


def _eps(data: Dataset, b: int, spec: QuantizerSpec) -> np.ndarray:
    lo, hi = data_ranges(data.states, data.inputs, spec)
    return effective_ranges(lo, hi, b, spec.guard, spec.dither)[1]


def test_identity_limit_is_theorem1_on_the_samples() -> None:
    """Identity dictionary: E[PP~] = PP + T diag(eps^2/12) and E[XP~] = XP, i.e. the letter's Theorem 1."""
    data = _data(runs=20, steps=30)
    lif = parse_lifting("identity", 2)
    spec = QuantizerSpec()
    (lim,) = large_data_limit(data, lif, [3], spec)
    assert lim.model is not None and lim.note == ""
    X = data.states[:, :-1].reshape(-1, 2)
    Xp = data.states[:, 1:].reshape(-1, 2)
    U = data.inputs.reshape(-1, 1)
    Phi = np.hstack([X, U])
    D = np.diag(_eps(data, 3, spec) ** 2 / 12)
    G = (Xp.T @ Phi) @ np.linalg.inv(Phi.T @ Phi + len(X) * D)
    np.testing.assert_allclose(lim.model.G, G, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(lim.regularizer, D, rtol=1e-10, atol=1e-14)


def _quadrature_moments(data: Dataset, lif, eps: np.ndarray, nodes: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """E[PP~], E[XP~] by tensor Gauss-Legendre quadrature of the lifted products over the uniform errors of
    every channel (exact for polynomials of degree < 2 * nodes per channel), sample by sample."""
    t, w = np.polynomial.legendre.leggauss(nodes)
    n, m = data.n, data.m
    grids = np.meshgrid(*[t * e / 2 for e in eps[:n]], indexing="ij")
    pts = np.stack([g.ravel() for g in grids], axis=1)  # error vectors of the states
    wts = np.prod(np.meshgrid(*[w / 2 for _ in range(n)], indexing="ij"), axis=0).ravel()
    L = lif.L
    PP = np.zeros((L + m, L + m))
    XP = np.zeros((L, L + m))
    for r in range(data.trajectories):
        for k in range(data.steps):
            x, xn, u = data.states[r, k], data.states[r, k + 1], data.inputs[r, k]
            Z = lif.lift(x + pts)  # (nodes^n, L)
            Ez = wts @ Z
            EzzT = (Z * wts[:, None]).T @ Z
            Ezn = wts @ lif.lift(xn + pts)
            PP[:L, :L] += EzzT
            PP[:L, L:] += np.outer(Ez, u)
            PP[L:, :L] += np.outer(u, Ez)
            PP[L:, L:] += np.outer(u, u) + np.diag(eps[n:] ** 2 / 12)
            XP += np.outer(Ezn, np.concatenate([Ez, u]))
    return PP, XP


@pytest.mark.parametrize("spec_text", ["poly:2", "poly:3"])
def test_polynomial_limit_matches_quadrature(spec_text: str) -> None:
    data = _data()
    lif = parse_lifting(spec_text, 2)
    spec = QuantizerSpec()
    (lim,) = large_data_limit(data, lif, [2], spec)
    assert lim.model is not None
    PP, XP = _quadrature_moments(data, lif, _eps(data, 2, spec))
    G = XP @ np.linalg.inv(PP)
    np.testing.assert_allclose(lim.model.G, G, rtol=1e-8, atol=1e-10)
    exact = exact_lifted_moments(data, lif)
    np.testing.assert_allclose(lim.regularizer, (PP - exact.PP) / exact.T, rtol=1e-8, atol=1e-10)


def test_error_moments_of_each_dither() -> None:
    eps = np.array([0.5, 2.0])
    mom = error_moments("subtractive", eps, 4)
    assert mom is not None
    np.testing.assert_allclose(mom[:, 1], [1, 0, 4 / 12, 0, 16 / 80])  # (eps/2)^l / (l + 1) for even l
    tp = error_moments("tpdf", eps, 2)
    assert tp is not None
    np.testing.assert_allclose(tp[2], eps**2 / 4)
    assert error_moments("tpdf", eps, 4) is None
    assert error_moments("rpdf", eps, 2) is None
    assert error_moments("none", eps, 2) is None


def test_no_limit_without_an_exact_formula() -> None:
    data = _data()
    (rbf,) = large_data_limit(data, parse_lifting("rbf:4", 2), [4])
    assert rbf.model is None and "radial" in rbf.note
    (tp,) = large_data_limit(data, parse_lifting("poly:2", 2), [4], QuantizerSpec(dither="tpdf"))
    assert tp.model is None and "TPDF" in tp.note
    (tp1,) = large_data_limit(data, parse_lifting("identity", 2), [4], QuantizerSpec(dither="tpdf"))
    assert tp1.model is not None
    (rp,) = large_data_limit(data, parse_lifting("identity", 2), [4], QuantizerSpec(dither="rpdf"))
    assert rp.model is None and "rpdf" in rp.note
    assert any("overload" in h for h in LARGE_DATA_HYPOTHESES)


def test_ls_quantized_edmd_goes_to_the_limit() -> None:
    """Monte-Carlo over dither draws on Van der Pol (poly:3): the LS error sits on the predicted limit, within the
    realizations' spread, while the limit is far from zero (a real bias, not a trivial match)."""
    system = get_nonlinear("van-der-pol")
    data = simulate_nonlinear(system, 400, 100, 0)
    lif = parse_lifting("poly:3", 2)
    ref = edmd(exact_lifted_moments(data, lif), lif.C, "ls")
    bits = (3, 4)
    lims = large_data_limit(data, lif, bits)
    errs = np.array(
        [
            [lifted_error(edmd(m, lif.C, "ls"), ref)[0] for m in quantized_lifted_moments(data, lif, bits, seed=s)]
            for s in range(6)
        ]
    )
    for j, lim in enumerate(lims):
        assert lim.model is not None
        pred = lifted_error(lim.model, ref)[0]
        assert pred > 0.2
        spread = errs[:, j].std() / np.sqrt(len(errs)) + 1e-3
        assert abs(errs[:, j].mean() - pred) < 5 * spread, (bits[j], errs[:, j], pred)
