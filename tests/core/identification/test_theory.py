import numpy as np
import pytest

from qsid_core import ConfigError, Experiment, QuantizerSpec, SweepConfig, run_sweep, theorem1_prediction
from qsid_core.control.bound import riccati_finite, ultimate_bound
from qsid_core.control.riccati import dare_stabilizing
from qsid_core.plant.systems import boeing747, dc_motor


def test_per_channel_form_reduces_to_letters_shared_formula():
    rng = np.random.default_rng(0)
    G = rng.normal(size=(3, 5))
    M = rng.normal(size=(5, 5))
    Sigma = M @ M.T + np.eye(5)
    eps = 0.37
    letter = G - eps**2 * G @ np.linalg.inv(12 * Sigma + eps**2 * np.eye(5))
    np.testing.assert_allclose(theorem1_prediction(G, Sigma, eps), letter, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(theorem1_prediction(G, Sigma, 0.0), G, atol=1e-12)


@pytest.mark.slow
def test_theorem1_matches_mean_ls_error_boeing_shared_b4():
    """Boeing, shared range, b = 4, 200 x 1000 data: mean LS error within 3% of the prediction."""
    ex = Experiment(
        SweepConfig(
            system="boeing747", bits=(4,), realizations=10, quantizer=QuantizerSpec(range_mode="shared"), mpc=None
        )
    )
    ident, th = ex.identification(4), ex.theory(4)
    assert ident.err_A.mean() == pytest.approx(th.err_A, rel=0.03)
    assert ident.err_B.mean() == pytest.approx(th.err_B, rel=0.03)


@pytest.mark.slow
def test_motor_slopes_per_channel_b4_to_12():
    """The letter: log10 error falls ~0.30 per bit (reports -0.301 for A and -0.322 for B)."""
    res = run_sweep(SweepConfig(system="dc-motor", bits="4:12", realizations=20, mpc=None))
    assert -0.36 <= res.slope_A <= -0.26, res.slope_A
    assert -0.36 <= res.slope_B <= -0.26, res.slope_B


def test_riccati_with_dare_terminal_is_stationary():
    s = dc_motor()
    X = dare_stabilizing(s.A, s.B, s.Q, s.R)
    np.testing.assert_allclose(riccati_finite(s.A, s.B, s.Q, s.R, X, 10), X, rtol=1e-9, atol=1e-9)


def test_ultimate_bound_scales_with_eps_squared():
    s = boeing747()
    X = dare_stabilizing(s.A, s.B, s.Q, s.R)
    dA, dB = 1e-3 * np.ones((4, 4)), 1e-3 * np.ones((4, 2))
    u1 = ultimate_bound(X, s.Q, s.R, dA, dB, x0=s.x0)
    u2 = ultimate_bound(X, s.Q, s.R, dA / 4, dB / 4, x0=s.x0)  # model error ~ eps^2: eps halved
    assert u1.delta / u2.delta == pytest.approx(4.0)
    # by hand, from the letter's formulas
    ev = np.linalg.eigvalsh(X)
    rho = np.sqrt(s.x0 @ X @ s.x0 / ev.min())  # the smallest ball holding {V <= V(x0)}
    wv = 2 * ev.max() * rho
    C = wv**2 * (np.linalg.norm(dA) ** 2 / (2 * 0.1) + np.linalg.norm(dB) ** 2 / 2)
    assert u1.delta == pytest.approx(np.sqrt(ev.max() / ev.min() * 2 * C / (0.5 * 0.1)))


@pytest.mark.parametrize("kw, match", [(dict(theta=0.0), "theta"), (dict(theta=1.0), "theta"), (dict(rho=-1.0), "rho")])
def test_bound_parameters_checked(kw, match):
    s = dc_motor()
    with pytest.raises(ConfigError, match=match):
        ultimate_bound(np.eye(3), s.Q, s.R, np.zeros((3, 3)), np.zeros((3, 2)), **kw)


def test_bound_needs_positive_definite_weights():
    with pytest.raises(ConfigError, match="positive definite"):
        ultimate_bound(np.eye(2), np.diag([1.0, 0.0]), np.eye(1), np.zeros((2, 2)), np.zeros((2, 1)))


def test_bound_shrinks_with_bits_in_sweep():
    res = run_sweep(SweepConfig(bits=(4, 6, 8), realizations=2, trajectories=20, steps=200, mpc=None))
    d = [res.theory[b].delta for b in (4, 6, 8)]
    assert d[0] > d[1] > d[2] > 0
    assert d[0] / d[1] == pytest.approx(16, rel=0.15)  # O(eps^2): 4 bits -> 2^4 ... 2 bits -> 16x


def test_realized_bound_uses_each_models_own_error_and_P():
    from qsid_core.control import realized_bounds

    s = boeing747()
    rng = np.random.default_rng(1)
    models = [(s.A + 1e-3 * rng.normal(size=s.A.shape), s.B + 1e-3 * rng.normal(size=s.B.shape)) for _ in range(3)]
    models.append((np.full_like(s.A, np.nan), s.B))  # a failed identification
    rb = realized_bounds(models, s.A, s.B, s.Q, s.R, None, 10, x0=s.x0)
    for (Ah, Bh), d, r in zip(models[:3], rb.delta[:3], rb.rho[:3]):
        P = riccati_finite(Ah, Bh, s.Q, s.R, dare_stabilizing(Ah, Bh, s.Q, s.R), 10)
        ub = ultimate_bound(P, s.Q, s.R, s.A - Ah, s.B - Bh, x0=s.x0)
        assert d == pytest.approx(ub.delta, rel=1e-6) and r == pytest.approx(ub.rho, rel=1e-6)
    assert np.isnan(rb.delta[3])
    assert rb.median == pytest.approx(np.median(rb.delta[:3])) and rb.max == pytest.approx(rb.delta[:3].max())


@pytest.mark.parametrize("x0, rho", [("sys", None), (None, None), ("sys", 2.0)])
def test_realized_bounds_at_once_equal_ultimate_bound_model_by_model(x0, rho):
    from qsid_core.control import realized_bounds
    from qsid_core.errors import MPCFailure

    s = boeing747()
    x0 = s.x0 if x0 == "sys" else None
    rng = np.random.default_rng(2)
    # small to huge model errors: finite bounds, overflowing ones, models without a stabilizing DARE solution
    models = [
        (s.A + e * rng.normal(size=s.A.shape), s.B + e * rng.normal(size=s.B.shape)) for e in np.logspace(-5, 1, 30)
    ]
    rb = realized_bounds(models, s.A, s.B, s.Q, s.R, None, 10, x0=x0, rho=rho)
    for (Ah, Bh), d, r in zip(models, rb.delta, rb.rho):
        try:
            P = riccati_finite(Ah, Bh, s.Q, s.R, dare_stabilizing(Ah, Bh, s.Q, s.R), 10)
        except MPCFailure:
            assert d == np.inf
            continue
        ub = ultimate_bound(P, s.Q, s.R, s.A - Ah, s.B - Bh, x0=x0, rho=rho)
        assert d == pytest.approx(ub.delta, rel=1e-6)
        assert r == pytest.approx(ub.rho, rel=1e-6, nan_ok=True)


def test_letter_bound_vs_realized_bound_motor_b16():
    """Issue 7: at b = 16 the letter's delta (Theorem 1's T -> inf errors) is ~10^4 smaller than the bound
    from the realizations' own finite-data errors (measured 5.75e-7 vs median 5.8e-3)."""
    ex = Experiment(SweepConfig(system="dc-motor", bits=(16,), realizations=10, mpc=None))
    th, rb = ex.theory(16), ex.realized_bound(16)
    assert th.rho > 0 and th.bound is not None and th.bound.rho == th.rho
    assert rb.median > 1000 * th.delta
    assert np.all(np.isfinite(rb.delta)) and rb.max >= rb.median
