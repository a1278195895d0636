"""riccati: the DARE (single and batched), the LQ fast-path parts, the state box."""

import numpy as np
import pytest

from qsid_core.control.riccati import LQParts, dare_batch, dare_stabilizing, lq_parts, state_box
from qsid_core.errors import FailureKind, MPCFailure
from qsid_core.plant.systems import boeing747, dc_motor


def _residual(A, B, Q, R, X):
    """DARE residual ``A'XA - X - A'XB (R + B'XB)^-1 B'XA + Q``, relative to ``|X|``."""
    S = R + B.T @ X @ B
    res = A.T @ X @ A - X - A.T @ X @ B @ np.linalg.solve(S, B.T @ X @ A) + Q
    return np.abs(res).max() / max(1.0, np.abs(X).max())


def _models(s, k, seed=0, scale=0.01):
    rng = np.random.default_rng(seed)
    return (
        np.stack([s.A + scale * rng.normal(size=s.A.shape) for _ in range(k)]),
        np.stack([s.B + scale * rng.normal(size=s.B.shape) for _ in range(k)]),
    )


@pytest.mark.parametrize("system", [dc_motor, boeing747])
def test_dare_solution_has_small_residual_and_stabilizes(system):
    s = system()
    X = dare_stabilizing(s.A, s.B, s.Q, s.R)
    assert _residual(s.A, s.B, s.Q, s.R, X) < 1e-10
    K = np.linalg.solve(s.R + s.B.T @ X @ s.B, s.B.T @ X @ s.A)
    assert np.abs(np.linalg.eigvals(s.A - s.B @ K)).max() < 1.0
    np.testing.assert_allclose(X, X.T)


@pytest.mark.parametrize("system", [dc_motor, boeing747])
def test_batched_dare_equals_scipy_per_model(system):
    s = system()
    A, B = _models(s, 6)
    X, ok = dare_batch(A, B, s.Q, s.R)
    assert ok.all()
    for k in range(len(A)):
        Xk = dare_stabilizing(A[k], B[k], s.Q, s.R)
        np.testing.assert_allclose(X[k], Xk, rtol=1e-9, atol=1e-9 * np.abs(Xk).max())
        assert _residual(A[k], B[k], s.Q, s.R, X[k]) < 1e-10


def test_unstabilizable_model_is_a_dare_failure_in_both_solvers():
    A, B = np.eye(2) * 2, np.zeros((2, 1))
    with pytest.raises(MPCFailure) as ei:
        dare_stabilizing(A, B, np.eye(2), np.eye(1))
    assert ei.value.kind is FailureKind.DARE and ei.value.kind == "dare"
    X, ok = dare_batch(A[None], B[None], np.eye(2), np.eye(1))
    assert not ok[0] and np.isnan(X[0]).all()


def _condensed(A, B, Q, R, Qf, N):
    """H, G (g = G x0) and the cost constant matrix of the horizon-N problem, built by brute force."""
    n, m = B.shape
    Sx = np.vstack([np.linalg.matrix_power(A, k + 1) for k in range(N)])
    Su = np.zeros((N * n, N * m))
    for k in range(N):
        for j in range(k + 1):
            Su[k * n : (k + 1) * n, j * m : (j + 1) * m] = np.linalg.matrix_power(A, k - j) @ B
    Qb = np.kron(np.eye(N), Q)
    Qb[-n:, -n:] = Qf
    H = Su.T @ Qb @ Su + np.kron(np.eye(N), R)
    return H, Su.T @ Qb @ Sx, Sx.T @ Qb @ Sx + Q


@pytest.mark.parametrize("system", [dc_motor, boeing747])
def test_lq_parts_are_the_unconstrained_optimum_of_the_condensed_problem(system):
    s = system()
    N = 8
    A, B = _models(s, 3, seed=2)
    Qf = np.stack([dare_stabilizing(a, b, s.Q, s.R) for a, b in zip(A, B)])
    parts = lq_parts(A, B, s.Q, s.R, Qf, np.zeros(s.n), N, np.ones(s.m))
    assert isinstance(parts, LQParts)
    assert parts.F.shape == (3, N * s.m, s.n) and parts.bound.shape == (N * s.m,)
    x0 = np.linspace(1.0, -0.5, s.n)
    for k in range(3):
        H, G, C = _condensed(A[k], B[k], s.Q, s.R, Qf[k], N)
        U = -np.linalg.solve(H, G @ x0)  # minimiser of U'HU + 2 x0'G'U
        np.testing.assert_allclose(parts.F[k] @ x0 + parts.f[k], U, atol=1e-9 * max(1, np.abs(U).max()))
        J = U @ H @ U + 2 * x0 @ G.T @ U + x0 @ C @ x0
        p = parts.model(k)
        assert x0 @ p.P0 @ x0 + 2 * p.p0 @ x0 + p.c0 == pytest.approx(J, rel=1e-9)


def test_batched_lq_parts_equal_single_model_parts():
    s = boeing747()
    A, B = _models(s, 4, seed=3)
    Qf = np.stack([dare_stabilizing(a, b, s.Q, s.R) for a, b in zip(A, B)])
    r = np.array([0.1, 0.0, -0.2, 0.0])
    batch = lq_parts(A, B, s.Q, s.R, Qf, r, 6, np.ones(2), x_max=np.full(4, 50.0))
    for k in range(4):
        one = lq_parts(A[k : k + 1], B[k : k + 1], s.Q, s.R, Qf[k : k + 1], r, 6, np.ones(2), x_max=np.full(4, 50.0))
        for name in ("K", "kf", "P0", "p0", "c0", "F", "f"):
            np.testing.assert_allclose(getattr(batch, name)[k], getattr(one, name)[0], rtol=1e-12, atol=1e-12)
    assert batch.finite().all()


def test_state_box_bounds_every_predicted_state_and_the_terminal_one():
    assert state_box(2, 3) is None
    b = state_box(2, 3, x_max=np.array([5.0, 6.0]), xf_max=np.array([1.0, 9.0]))
    np.testing.assert_array_equal(b, [5, 6, 5, 6, 1, 6])
    b2 = state_box(2, 2, xf_max=np.array([1.0, 2.0]))
    np.testing.assert_array_equal(b2, [np.inf, np.inf, 1, 2])
