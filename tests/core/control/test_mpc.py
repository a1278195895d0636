import numpy as np
import pytest

from qsid_core import ConfigError, MPCConfig, MPCController, MPCFailure, run_closed_loops
from qsid_core.control.riccati import dare_stabilizing
from qsid_core.plant.systems import boeing747, dc_motor


def _ctrl(s, **kw):
    w = MPCConfig(**kw).resolve(s)
    return MPCController(s.A, s.B, w.Q, w.R, kw.get("horizon", 10), w.u_max, w.x_max, w.xf_max, w.x_ref, w.Qf)


@pytest.mark.parametrize("system", [dc_motor, boeing747])
@pytest.mark.parametrize("scale", [0.3, 1.0, 5.0, 30.0])
def test_fast_path_equals_osqp(system, scale):
    s = system()
    c = _ctrl(s)
    rng = np.random.default_rng(1)
    for _ in range(5):
        x = scale * rng.uniform(-1, 1, s.n)
        u_q, J_q = c.solve_osqp(x)
        f = c.fast(x)
        if f is not None:  # unconstrained optimum feasible: it is the QP optimum
            np.testing.assert_allclose(f[0], u_q, atol=1e-6)
            assert f[1] == pytest.approx(J_q, rel=1e-6, abs=1e-9)
        else:  # a bound is active: OSQP respects it
            assert np.all(np.abs(u_q) <= 1.0 + 1e-12)


def test_fast_path_equals_osqp_with_reference_and_state_box():
    s = dc_motor()
    c = _ctrl(s, x_ref=(0.2, 0.0, 0.0), x_max=50.0, xf_max=40.0)
    x = np.array([0.5, 0.1, -0.1])
    f = c.fast(x)
    assert f is not None
    u_q, J_q = c.solve_osqp(x)
    np.testing.assert_allclose(f[0], u_q, atol=1e-6)
    assert f[1] == pytest.approx(J_q, rel=1e-6)


@pytest.mark.parametrize("system", [dc_motor, boeing747])
def test_exact_model_regulates_to_origin_and_constraints_hold(system):
    s = system()
    loops = run_closed_loops([(s.A, s.B)], s.A, s.B, MPCConfig(steps=300), s)
    assert loops.failure == [""]
    assert np.linalg.norm(loops.states[0, -1]) < 1e-6
    assert np.all(np.abs(loops.inputs) <= 1.0 + 1e-12)
    assert np.isfinite(loops.cost[0]) and loops.cost[0] > 0
    # the realised cost of the exact model is the predicted optimum J*(x0) up to the tail
    assert loops.cost[0] == pytest.approx(loops.J0[0], rel=1e-3)


def test_active_input_bound_uses_osqp_and_holds():
    s = boeing747()
    cfg = MPCConfig(x0=(20.0, 20.0, 0.0, 0.0), u_max=0.5, steps=60)
    loops = run_closed_loops([(s.A, s.B)], s.A, s.B, cfg, s)
    assert loops.qp_steps > 0
    assert np.all(np.abs(loops.inputs) <= 0.5 + 1e-12)
    assert np.max(np.abs(loops.inputs)) == pytest.approx(0.5, abs=1e-6)
    # the engine's loop applies exactly what a per-step controller gives
    c = _ctrl(s, u_max=0.5)
    x = np.array([20.0, 20.0, 0.0, 0.0])
    for t in range(10):
        u, _, _ = c.solve(x)
        np.testing.assert_allclose(loops.inputs[0, t], u, atol=1e-7)
        x = s.A @ x + s.B @ u


def test_state_box_is_respected_in_prediction():
    s = dc_motor()
    c = _ctrl(s, x_max=(10.0, 0.05, 10.0))
    u, J = c.solve_osqp(np.array([1.0, 0.0, 0.0]))
    assert np.all(np.isfinite(u))
    f = c.fast(np.array([1.0, 0.0, 0.0]))
    assert f is None  # the speed box is active for this start


def test_failures_are_recorded_not_raised():
    s = dc_motor()
    bad_model = (np.eye(3) * 1.5, np.zeros((3, 2)))  # unstable, no input: no stabilizing DARE solution
    infeasible = dict(x_max=(1e-3, 1e-3, 1e-3))
    loops = run_closed_loops([bad_model, (s.A, s.B)], s.A, s.B, MPCConfig(steps=5), s)
    assert loops.failure[0] == "dare" and loops.failure[1] == ""
    assert np.isnan(loops.cost[0]) and np.isfinite(loops.cost[1])
    assert "DARE" in loops.messages[0]
    loops2 = run_closed_loops([(s.A, s.B)], s.A, s.B, MPCConfig(steps=5, **infeasible), s)
    assert loops2.failure[0] == "infeasible" and loops2.failed.all()


def test_diverging_closed_loop_is_a_failure():
    s = dc_motor()
    # a wildly wrong model (the DARE is solvable): its inputs push the 3x-unstable true system the wrong way
    loops = run_closed_loops([(s.A, -s.B * 0.01)], s.A * 3, s.B, MPCConfig(steps=200), s)
    assert loops.failure[0] == "diverged"


def test_dare_failure_kind():
    with pytest.raises(MPCFailure) as ei:
        dare_stabilizing(np.eye(2) * 2, np.zeros((2, 1)), np.eye(2), np.eye(1))
    assert ei.value.kind == "dare"


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(horizon=0), "horizon"),
        (dict(steps=0), "mpc steps"),
        (dict(u_max=0.0), "u_max must be positive"),
        (dict(u_max=(1.0, -1.0)), "u_max must be positive"),
        (dict(R=(0.0, 1.0)), "R diagonal"),
        (dict(Q=(-1.0, 1.0, 1.0)), "Q diagonal"),
        (dict(x0=(1.0, float("nan"))), "finite"),
    ],
)
def test_bad_mpc_config(kw, match):
    with pytest.raises(ConfigError, match=match):
        MPCConfig(**kw)


def test_weights_must_fit_the_system():
    with pytest.raises(ConfigError, match="Q must have 1 or 3 entries"):
        MPCConfig(Q=(1.0, 2.0)).resolve(dc_motor())


def _reference_loop(model, s, cfg):
    """Plain per-step MPC: the definition the batched, speculative engine loop must reproduce."""
    w = cfg.resolve(s)
    c = MPCController(model[0], model[1], w.Q, w.R, cfg.horizon, w.u_max, w.x_max, w.xf_max, w.x_ref, w.Qf)
    x = w.x0.copy()
    X, U, J0, cost = [x], [], None, 0.0
    for t in range(cfg.steps):
        u, J, _ = c.solve(x)
        J0 = J if t == 0 else J0
        cost += (x - w.x_ref) @ w.Q @ (x - w.x_ref) + u @ w.R @ u
        x = s.A @ x + s.B @ u
        X.append(x)
        U.append(u)
    return np.array(X), np.array(U), cost, J0


@pytest.mark.parametrize("u_max", [1.0, 0.4])
def test_batched_speculative_loop_equals_per_step_mpc(u_max):
    s = boeing747()
    rng = np.random.default_rng(0)
    models = [(s.A, s.B)] + [
        (s.A + 0.01 * rng.normal(size=s.A.shape), s.B + 0.05 * rng.normal(size=s.B.shape)) for _ in range(5)
    ]
    cfg = MPCConfig(x0=(8.0, 8.0, 0.0, 0.0), u_max=u_max, steps=40)
    loops = run_closed_loops(models, s.A, s.B, cfg, s)
    if u_max < 1:
        assert loops.qp_steps > 0
    for i, mdl in enumerate(models):
        if loops.failure[i]:
            continue
        X, U, cost, J0 = _reference_loop(mdl, s, cfg)
        np.testing.assert_allclose(loops.states[i], X, atol=1e-6)
        np.testing.assert_allclose(loops.inputs[i], U, atol=1e-6)
        assert loops.cost[i] == pytest.approx(cost, rel=1e-6)
        assert loops.J0[i] == pytest.approx(J0, rel=1e-6)


def test_batched_doubling_dare_matches_scipy():
    from qsid_core.control.riccati import dare_batch

    rng = np.random.default_rng(3)
    systems = [dc_motor(), boeing747()]
    for s in systems:
        As = np.stack([s.A + 0.02 * rng.normal(size=s.A.shape) for _ in range(6)] + [np.eye(s.n) * 1.5])
        Bs = np.stack([s.B + 0.02 * rng.normal(size=s.B.shape) for _ in range(6)] + [np.zeros_like(s.B)])
        X, ok = dare_batch(As, Bs, s.Q, s.R)
        assert ok[:6].all() and not ok[6]  # the last model cannot be stabilized
        for k in range(6):
            np.testing.assert_allclose(X[k], dare_stabilizing(As[k], Bs[k], s.Q, s.R), rtol=1e-8, atol=1e-10)


def test_resolve_returns_named_weights_with_shapes():
    from qsid_core import MPCWeights

    s = boeing747()
    w = MPCConfig(u_max=0.3, x_max=5.0).resolve(s)
    assert isinstance(w, MPCWeights)
    assert w.Q.shape == (4, 4) and w.R.shape == (2, 2) and w.x0.shape == (4,) and w.x_ref.shape == (4,)
    np.testing.assert_array_equal(w.u_max, [0.3, 0.3])
    np.testing.assert_array_equal(w.x_max, [5.0] * 4)
    assert w.Qf is None and w.xf_max is None
    assert not hasattr(w, "__getitem__")  # attributes only: no dict-style reads left anywhere


def test_failure_kinds_are_strings_in_json_and_messages():
    import json

    from qsid_core import FailureKind
    from qsid_core.control.mpc import FAILURE_KINDS

    assert FAILURE_KINDS == ("ident", "dare", "infeasible", "max_iter", "solver", "diverged")
    assert FailureKind("dare") is FailureKind.DARE and FailureKind.DARE == "dare"
    assert json.dumps({FailureKind.MAX_ITER: [FailureKind.DIVERGED]}) == '{"max_iter": ["diverged"]}'
    assert f"{FailureKind.INFEASIBLE}" == "infeasible" and str(FailureKind.SOLVER) == "solver"
    assert MPCFailure("ident", "x").kind is FailureKind.IDENT


def test_unknown_solver_is_a_config_error():
    with pytest.raises(ConfigError, match="solver"):
        MPCConfig(solver="cplex")


@pytest.mark.parametrize("solver", ["daqp", "osqp"])
def test_controller_qp_respects_the_box_and_matches_the_other_solver(solver):
    s = boeing747()
    c = _ctrl(s, u_max=0.3)
    c.solver = solver
    x = np.array([20.0, 20.0, 0.0, 0.0])
    u, J = c.solve_qp(x)
    c2 = _ctrl(s, u_max=0.3)
    u2, J2 = c2.solve_osqp(x) if solver == "daqp" else c2.solve_qp(x)
    assert np.all(np.abs(u) <= 0.3) and np.abs(u).max() == pytest.approx(0.3)
    np.testing.assert_allclose(u, u2, atol=1e-7)
    assert J == pytest.approx(J2, rel=1e-7)
