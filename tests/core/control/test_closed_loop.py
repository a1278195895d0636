"""closed_loop: batched closed loops equal an independent per-step reference; failures have one kind."""

import numpy as np
import pytest
from scipy.optimize import lsq_linear

import qsid_core.control.closed_loop as closed_loop
import qsid_core.control.loop_kernel as loop_kernel
import qsid_core.control.loop_steps as loop_steps
from qsid_core import FailureKind, LTISystem, MPCConfig, run_closed_loops
from qsid_core.control.riccati import dare_stabilizing
from qsid_core.plant.systems import boeing747, dc_motor

SATURATED = dict(x0=(20.0, 20.0, 0.0, 0.0), u_max=0.3, steps=50)  # the saturated Boeing case


def _boeing_models(k, seed=0):
    s = boeing747()
    rng = np.random.default_rng(seed)
    return s, [(s.A, s.B)] + [
        (s.A + 0.01 * rng.normal(size=s.A.shape), s.B + 0.05 * rng.normal(size=s.B.shape)) for _ in range(k)
    ]


def _reference(model, s, cfg):
    """Per-step MPC by an independent exact solver: the condensed box QP as bounded least squares (BVLS)."""
    A, B = model
    w = cfg.resolve(s)
    n, m, N = s.n, s.m, cfg.horizon
    Qf = dare_stabilizing(A, B, w.Q, w.R)
    Sx = np.vstack([np.linalg.matrix_power(A, k + 1) for k in range(N)])
    Su = np.zeros((N * n, N * m))
    for k in range(N):
        for j in range(k + 1):
            Su[k * n : (k + 1) * n, j * m : (j + 1) * m] = np.linalg.matrix_power(A, k - j) @ B
    Qb = np.kron(np.eye(N), w.Q)
    Qb[-n:, -n:] = Qf
    H = Su.T @ Qb @ Su + np.kron(np.eye(N), w.R)
    L = np.linalg.cholesky(H)  # U'HU + 2g'U = |L'U + L^-1 g|^2 - const
    ub = np.tile(w.u_max, N)
    x, us = w.x0.copy(), []
    for _ in range(cfg.steps):
        g = Su.T @ Qb @ Sx @ x
        res = lsq_linear(L.T, -np.linalg.solve(L, g), bounds=(-ub, ub), method="bvls", tol=1e-15)
        u = res.x[:m]
        us.append(u)
        x = s.A @ x + s.B @ u
    return np.array(us)


@pytest.mark.parametrize("path", ["loop", "batched", "numpy"])
def test_saturated_loops_equal_an_exact_reference(path, monkeypatch):
    from qsid_core.quantization import kernels

    if path != "numpy" and not kernels.AVAILABLE:
        pytest.skip(kernels.REASON)
    # loop: the compiled closed loop; batched: the compiled active-set kernel per step; numpy: its numpy version
    monkeypatch.setattr(kernels, "AVAILABLE", path != "numpy")
    if path == "batched":
        monkeypatch.setattr(closed_loop, "eligible", lambda loops: False)
    s, models = _boeing_models(5)
    cfg = MPCConfig(**SATURATED)
    loops = run_closed_loops(models, s.A, s.B, cfg, s)
    assert loops.failure == [""] * len(models)
    assert loops.qp_steps > 0 and np.abs(loops.inputs).max() == pytest.approx(0.3)
    for i, mdl in enumerate(models):
        np.testing.assert_allclose(loops.inputs[i], _reference(mdl, s, cfg), rtol=0, atol=1e-8)


@pytest.mark.parametrize("path", ["batched", "compiled"])
def test_daqp_alone_equals_the_exact_reference(path, monkeypatch):
    # switch off the active-set iterations: every constrained step goes to DAQP
    if path == "batched":
        monkeypatch.setattr(closed_loop, "eligible", lambda loops: False)
        monkeypatch.setattr(
            loop_steps,
            "box_qp_batch",
            lambda H, g, ub, hi, lo: (np.full(g.shape, np.nan), np.zeros(len(g), dtype=bool)),
        )
    else:
        monkeypatch.setattr(loop_kernel, "PDAS_ITERS", 0)
    s, models = _boeing_models(2, seed=1)
    cfg = MPCConfig(**SATURATED)
    loops = run_closed_loops(models, s.A, s.B, cfg, s)
    for i, mdl in enumerate(models):
        np.testing.assert_allclose(loops.inputs[i], _reference(mdl, s, cfg), rtol=0, atol=1e-8)


def test_batched_loops_equal_loops_run_one_model_at_a_time():
    s, models = _boeing_models(4, seed=2)
    cfg = MPCConfig(**SATURATED)
    together = run_closed_loops(models, s.A, s.B, cfg, s)
    for i, mdl in enumerate(models):
        alone = run_closed_loops([mdl], s.A, s.B, cfg, s)
        np.testing.assert_allclose(together.inputs[i], alone.inputs[0], rtol=0, atol=1e-12)
        assert together.cost[i] == pytest.approx(alone.cost[0], rel=1e-12)
        assert together.J0[i] == pytest.approx(alone.J0[0], rel=1e-12)


def test_daqp_and_the_previous_osqp_engine_agree():
    s, models = _boeing_models(3, seed=3)
    a = run_closed_loops(models, s.A, s.B, MPCConfig(**SATURATED), s)
    b = run_closed_loops(models, s.A, s.B, MPCConfig(**SATURATED, solver="osqp"), s)
    assert a.qp_steps == b.qp_steps > 0
    np.testing.assert_allclose(a.inputs, b.inputs, atol=1e-7)
    np.testing.assert_allclose(a.J0, b.J0, rtol=1e-7)


@pytest.mark.parametrize("x_max", [0.2, 0.05])
def test_state_box_as_daqp_rows_equals_osqp(x_max):
    s = dc_motor()
    kw = dict(x0=(1.0, 0.0, 0.0), x_max=(10.0, x_max, 10.0), steps=30)
    a = run_closed_loops([(s.A, s.B)], s.A, s.B, MPCConfig(**kw), s)
    b = run_closed_loops([(s.A, s.B)], s.A, s.B, MPCConfig(**kw, solver="osqp"), s)
    assert a.failure == [""] and a.qp_steps > 0
    np.testing.assert_allclose(a.inputs, b.inputs, atol=1e-6)
    assert np.abs(a.states[0, :, 1]).max() <= x_max * (1 + 1e-9)  # the exact model keeps its predicted box


def test_reference_tracking_with_saturation_equals_osqp():
    s = dc_motor()
    kw = dict(x0=(0.0, 0.0, 0.0), x_ref=(10.0, 0.0, 0.0), u_max=0.2, steps=40)
    a = run_closed_loops([(s.A, s.B)], s.A, s.B, MPCConfig(**kw), s)
    b = run_closed_loops([(s.A, s.B)], s.A, s.B, MPCConfig(**kw, solver="osqp"), s)
    assert a.qp_steps > 0
    np.testing.assert_allclose(a.inputs, b.inputs, atol=1e-6)


def test_diverging_loop_is_a_diverged_failure():
    toy = LTISystem("toy", np.array([[2.0]]), np.array([[1.0]]), x0=np.array([1.0]), Q=np.eye(1), R=np.eye(1))
    # the model has the input's sign wrong: every input pushes the unstable plant further out
    loops = run_closed_loops([(toy.A, -toy.B)], toy.A, toy.B, MPCConfig(steps=200, u_max=1e6), toy)
    assert loops.failure == [FailureKind.DIVERGED]
    assert loops.failure[0] == "diverged" and "diverged" in loops.messages[0]
    assert np.isnan(loops.cost[0]) and np.isnan(loops.states[0]).all()


def test_iteration_limit_is_a_max_iter_failure():
    s = dc_motor()
    loops = run_closed_loops(
        [(s.A, s.B)], s.A, s.B, MPCConfig(x0=(1.0, 0.0, 0.0), x_max=(10.0, 0.1, 10.0), steps=30, max_iter=1), s
    )
    assert loops.failure == [FailureKind.MAX_ITER]


def test_missing_model_is_an_ident_failure_and_others_still_run():
    s = dc_motor()
    nan_model = (np.full((3, 3), np.nan), np.full((3, 2), np.nan))
    loops = run_closed_loops([nan_model, (s.A, s.B)], s.A, s.B, MPCConfig(steps=10), s)
    assert loops.failure == [FailureKind.IDENT, ""]
    assert np.isfinite(loops.cost[1])


def test_compiled_active_set_kernel_equals_the_numpy_iterations(monkeypatch):
    from qsid_core.control.condensed_qp import box_qp_batch
    from qsid_core.quantization import kernels

    if not kernels.AVAILABLE:
        pytest.skip(kernels.REASON)
    rng = np.random.default_rng(5)
    S, nU = 40, 12
    Z = rng.normal(size=(S, nU, nU))
    H = Z @ np.swapaxes(Z, 1, 2) + 0.5 * np.eye(nU)
    g = 3 * rng.normal(size=(S, nU))
    ub = np.full(nU, 0.4)
    none = np.zeros((S, nU), dtype=bool)
    Uc, okc = kernels.box_qp_pdas(H, g, ub, none, none, 30)
    monkeypatch.setattr(kernels, "AVAILABLE", False)
    Un, okn = box_qp_batch(H, g, ub, none, none, 30)
    both = okc & okn
    assert both.sum() >= S // 2
    np.testing.assert_allclose(Uc[both], Un[both], atol=1e-12)
    for k in np.flatnonzero(both):  # and both are the exact optimum (BVLS)
        L = np.linalg.cholesky(H[k])
        ref = lsq_linear(L.T, -np.linalg.solve(L, g[k]), bounds=(-ub, ub), method="bvls", tol=1e-15).x
        np.testing.assert_allclose(Uc[k], ref, atol=1e-9)
