"""The compiled closed loop (qsid_core.control.loop_kernel) applies the same inputs as the exact DAQP and OSQP paths."""

import warnings
from dataclasses import replace

import numpy as np
import pytest

import qsid_core.control.closed_loop as closed_loop
import qsid_core.control.loop_kernel as loop_kernel
import qsid_core.control.loop_steps as loop_steps
from qsid_core import LTISystem, MPCConfig, run_closed_loops
from qsid_core.quantization import kernels

pytestmark = pytest.mark.skipif(not kernels.AVAILABLE, reason=kernels.REASON)


def _no_active_set(H, g, ub, hi, lo):
    return np.full(g.shape, np.nan), np.zeros(len(g), dtype=bool)


def _exact(models, s, cfg, monkeypatch):
    """The same loops with every constrained step solved by DAQP alone (no compiled loop, no active-set guess)."""
    with monkeypatch.context() as mp:
        mp.setattr(closed_loop, "eligible", lambda loops: False)
        mp.setattr(loop_steps, "box_qp_batch", _no_active_set)
        return run_closed_loops(models, s.A, s.B, cfg, s)


def _case(seed: int):
    """A random plant (possibly unstable), perturbed models, a small input box and a far initial state."""
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(1, 5)), int(rng.integers(1, 3))
    A = rng.normal(size=(n, n))
    A *= rng.uniform(0.6, 1.15) / max(np.abs(np.linalg.eigvals(A)).max(), 1e-9)
    B = rng.normal(size=(n, m))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a random (A, B) may be uncontrollable: the MPC must still run or fail cleanly
        s = LTISystem(
            "random",
            A,
            B,
            x0=rng.normal(size=n) * 10,
            Q=np.diag(rng.uniform(0.1, 10, n)),
            R=np.diag(rng.uniform(0.01, 1, m)),
        )
    models = [(A, B)] + [
        (A + rng.uniform(0.001, 0.1) * rng.normal(size=A.shape), B + 0.1 * rng.normal(size=B.shape)) for _ in range(5)
    ]
    if seed % 7 == 0:
        models.append((np.full_like(A, np.nan), np.full_like(B, np.nan)))  # a failed identification
    if seed % 5 == 0:
        models.append((A, -B))  # inputs with the wrong sign: an unstable plant diverges
    cfg = MPCConfig(
        horizon=int(rng.integers(1, 15)),
        steps=int(rng.integers(5, 60)),
        u_max=tuple(rng.uniform(0.05, 1.0, m)),
        x_ref=tuple(rng.normal(size=n)) if seed % 3 == 0 else None,
        verify_steps=2000,
    )
    return s, models, cfg


def _agree(a, b):
    assert a.failure == b.failure
    ok = ~np.array([bool(f) for f in a.failure])
    assert a.qp_steps == b.qp_steps
    np.testing.assert_allclose(a.inputs[ok], b.inputs[ok], rtol=0, atol=1e-6)
    np.testing.assert_allclose(a.cost[ok], b.cost[ok], rtol=1e-6)
    np.testing.assert_allclose(a.J0[ok], b.J0[ok], rtol=1e-6)
    assert a.outcome == b.outcome
    np.testing.assert_array_equal(a.verdict_steps, b.verdict_steps)


@pytest.mark.parametrize("seed", range(40))
def test_compiled_loop_equals_daqp_on_random_saturated_cases(seed, monkeypatch):
    s, models, cfg = _case(seed)
    a = run_closed_loops(models, s.A, s.B, cfg, s)
    _agree(a, _exact(models, s, cfg, monkeypatch))


@pytest.mark.parametrize("iters", [0, 1, 2])
def test_unsettled_steps_fall_back_to_daqp(iters, monkeypatch):
    # with 0-2 active-set iterations most constrained steps cannot settle in the kernel and go to DAQP
    monkeypatch.setattr(loop_kernel, "PDAS_ITERS", iters)
    for seed in (1, 2, 4, 10):
        s, models, cfg = _case(seed)
        a = run_closed_loops(models, s.A, s.B, cfg, s)
        _agree(a, _exact(models, s, cfg, monkeypatch))


def test_compiled_loop_equals_the_osqp_engine():
    from qsid_core.plant.systems import boeing747

    s = boeing747()
    rng = np.random.default_rng(5)
    models = [(s.A, s.B)] + [
        (s.A + 0.01 * rng.normal(size=s.A.shape), s.B + 0.05 * rng.normal(size=s.B.shape)) for _ in range(6)
    ]
    kw = dict(x0=(20.0, 20.0, 0.0, 0.0), u_max=0.3, steps=50)
    a = run_closed_loops(models, s.A, s.B, MPCConfig(**kw), s)
    b = run_closed_loops(models, s.A, s.B, MPCConfig(**kw, solver="osqp"), s)
    assert a.qp_steps == b.qp_steps > 0
    np.testing.assert_allclose(a.inputs, b.inputs, rtol=0, atol=1e-6)
    assert a.outcome == b.outcome


def test_degenerate_models_agree():
    # an input that barely acts (the Hessian is R plus almost nothing) and a model equal to the plant
    s, models, cfg = _case(3)
    A, B = models[0]
    models = [(A, B * 1e-9), (A, B), (A * 0.0, B)]
    a = run_closed_loops(models, s.A, s.B, cfg, s)
    with pytest.MonkeyPatch.context() as mp:
        _agree(a, _exact(models, s, cfg, mp))


@pytest.mark.parametrize(
    "extra, compiled",
    [({}, True), ({"x_max": 5.0}, False), ({"disturbance": 0.1}, False), ({"solver": "osqp"}, False)],
)
def test_the_compiled_loop_runs_only_where_it_applies(extra, compiled, monkeypatch):
    s, models, cfg = _case(2)
    noisy = []  # per compiled run: whether its loops were disturbed
    real = loop_kernel.run_compiled
    monkeypatch.setattr(closed_loop, "run_compiled", lambda *a: noisy.append(a[0].noise is not None) or real(*a))
    run_closed_loops(models, s.A, s.B, replace(cfg, **extra), s)
    if "disturbance" in extra:  # only the verdicts' noise-free run of the same law is compiled
        assert noisy and not any(noisy)
    else:
        assert bool(noisy) == compiled
