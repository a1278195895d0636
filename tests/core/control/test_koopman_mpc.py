"""Koopman MPC: the letter's MPC on a lifted model, run on the true plant."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from qsid_core.control import MPCConfig, run_closed_loops, run_koopman_loops
from qsid_core.identification import edmd, exact_lifted_moments, parse_lifting, quantized_lifted_moments
from qsid_core.plant import NonlinearSystem, get_nonlinear, get_system, simulate, simulate_nonlinear


def test_identity_lifting_on_a_linear_preset_is_exactly_the_linear_mpc():
    s = get_system("dc-motor")
    d = simulate(s, 40, 100, seed=0)
    lf = parse_lifting("identity", s.n)
    models = [edmd(m, lf.C, "ls") for m in quantized_lifted_moments(d, lf, [2, 4, 8], seed=0)]
    cfg = MPCConfig(verify_steps=None)
    ko = run_koopman_loops(models, lf, s, cfg)
    lin = run_closed_loops([(m.A, m.B) for m in models], s.A, s.B, cfg, s)
    np.testing.assert_allclose(ko.states, lin.states, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(ko.inputs, lin.inputs, rtol=1e-12, atol=1e-12)


def test_koopman_mpc_from_unquantized_edmd_regulates_van_der_pol_to_the_origin():
    s = get_nonlinear("van-der-pol")
    d = simulate_nonlinear(s, 300, 100, seed=0)
    lf = parse_lifting("poly:3", 2)
    ref = edmd(exact_lifted_moments(d, lf), lf.C)
    out = run_koopman_loops([ref, None], lf, s, MPCConfig(horizon=20, steps=200))
    # near the origin, not at it: the lifted model's affine term leaves an offset, so the loop is bounded
    assert out.outcome == ["bounded", "failed"] and out.counts()["converged"] == 0
    assert out.within_radius.tolist() == [True, False] and np.isnan(out.settled_offset[1])
    tail = np.linalg.norm(out.states[0, -20:], axis=1).mean()
    assert out.settled_offset[0] == pytest.approx(tail) and 1e-6 * np.linalg.norm(s.x0) < tail < 0.05
    assert out.offset_stats() == {"median": out.settled_offset[0], "max": out.settled_offset[0]}
    assert np.linalg.norm(out.states[0, -1]) < out.radius and np.all(np.abs(out.inputs[0]) <= 1.0)
    # without control the plant stays on its limit cycle (|x| about 2), so the convergence is the MPC's doing
    x = np.array([s.x0])
    for _ in range(200):
        x = s.step(x, np.zeros((1, 1)))
    assert np.linalg.norm(x) > 1.0


def test_a_loop_that_leaves_the_sane_box_is_diverged():
    s = NonlinearSystem("runaway", lambda x, u: x + 0.0 * u, 1, 1, x0=(1.0,), box=5.0)  # xdot = x, |u| <= 0.01 too weak
    lf = parse_lifting("identity", 1)

    class Wrong:  # a model that believes u pushes the wrong way
        A, B, C = np.array([[1.05]]), np.array([[-0.05]]), np.eye(1)

    out = run_koopman_loops([Wrong()], lf, s, MPCConfig(steps=100, u_max=0.01))
    assert out.outcome == ["diverged"] and np.isnan(out.states[0, -1, 0])


def test_a_loop_that_settles_at_the_origin_converged():
    # the identity lifting of a linear plant's true model: no affine term, the loop goes to the origin itself
    s = get_system("dc-motor")
    lf = parse_lifting("identity", s.n)
    model = SimpleNamespace(A=s.A, B=s.B, C=np.eye(s.n))
    out = run_koopman_loops([model], lf, s, MPCConfig(verify_steps=None, steps=400))
    assert out.outcome == ["converged"] and out.settled_offset[0] <= 1e-6 * np.linalg.norm(s.x0)
    assert out.within_radius.tolist() == [True]
