"""Closed loops judged on the true plant (converged / bounded / diverged / failed) and the stability tests."""

from dataclasses import replace

import numpy as np
import pytest

from qsid_core.control import (
    certify,
    complex_stability_radius,
    controllability_margin,
    lyapunov_batch,
    small_gain_holds,
    small_gain_margin,
    spectral_radius,
)
from qsid_core.control.mpc import MPCConfig
from qsid_core.control.verdicts import OUTCOMES
from qsid_core.plant.lti import LTISystem
from qsid_core.studies.config import SweepConfig
from qsid_core.studies.experiment import Experiment

SMALL = dict(trajectories=50, steps=300, realizations=12)


def _agree_with_long_run(system: str, bits, **data):
    """Every verdict against a 3,000-step run of the same loops (no verdicts there)."""
    ex = Experiment(SweepConfig(system=system, bits=bits, **data))
    long = ex.with_config(replace(ex.config, mpc=MPCConfig(steps=3000, verify_steps=None)))
    x0 = np.linalg.norm(ex.system.x0)
    seen = set()
    for b in bits:
        v, lp = ex.closed_loops(b), long.closed_loops(b)
        assert len(v.outcome) == ex.config.realizations and set(v.outcome) <= set(OUTCOMES)
        fn = lp.final_state_norm
        early = np.linalg.norm(lp.states[:, 50], axis=1)
        for r, o in enumerate(v.outcome):
            seen.add(o)
            if o == "converged":
                assert v.spectral_radius[r] < 1
                assert fn[r] < 0.5 * x0 and fn[r] <= max(early[r], 1e-300) * 1.5  # decays, never regrows
            elif o == "bounded":
                assert np.isfinite(fn[r]) and fn[r] > 1e-3 * x0  # still away from the reference at 3,000
            elif o == "diverged":
                assert lp.failure[r] == "diverged" or fn[r] > 1e3 * x0
    return seen


@pytest.mark.slow
def test_verdicts_agree_with_a_3000_step_run_on_both_presets():
    assert _agree_with_long_run("dc-motor", (1, 2, 3, 4)) >= {"converged", "bounded"}
    assert _agree_with_long_run("boeing747", (1, 2, 3, 4)) >= {"converged", "bounded"}


@pytest.mark.slow
def test_paper_scale_counts_the_unstable_loops():
    """Boeing b = 2: 48 of 50 loops have a true closed loop with spectral radius > 1 (they used to count as successes)."""
    ex = Experiment(SweepConfig(system="boeing747", bits=(2, 8)))
    b2, b8 = ex.closed_loops(2), ex.closed_loops(8)
    assert b2.outcome_counts()["converged"] / 50 <= 0.20
    assert np.sum(b2.spectral_radius > 1) >= 40 and not any(b2.failure)  # none failed, yet most did not converge
    assert b8.outcome_counts()["converged"] / 50 >= 0.95
    motor = Experiment(SweepConfig(system="dc-motor", bits=(1,))).closed_loops(1)
    assert motor.outcome_counts()["converged"] < 50 and np.nanmax(motor.spectral_radius) > 1


def test_unstable_plant_loops_diverge_and_stable_ones_converge():
    s = LTISystem("unstable2", np.array([[1.05, 0.2], [0.0, 0.8]]), np.array([[0.1], [1.0]]))
    ex = Experiment(SweepConfig(system=s, bits=(1, 6), realizations=20, trajectories=20, steps=40))
    low, high = ex.closed_loops(1).outcome_counts(), ex.closed_loops(6).outcome_counts()
    assert low["diverged"] > 0 and high == {"converged": 20, "bounded": 0, "diverged": 0, "failed": 0}


def test_verdicts_off_and_budget_zero():
    cfg = SweepConfig(system="boeing747", bits=(2,), **SMALL)
    off = Experiment(replace(cfg, mpc=MPCConfig(verify_steps=None))).closed_loops(2)
    assert off.outcome == [] and off.outcome_counts() == {}
    zero = Experiment(replace(cfg, mpc=MPCConfig(verify_steps=0))).closed_loops(2)
    assert set(zero.outcome) <= {"converged", "bounded"} and (zero.verdict_steps == 50).all()
    with pytest.raises(ValueError, match="verify steps"):
        MPCConfig(verify_steps=-1)


def test_failed_models_are_failed_not_converged():
    cfg = SweepConfig(system="dc-motor", bits=(4,), **SMALL)
    from qsid_core.control.closed_loop import run_closed_loops

    s = Experiment(cfg).system
    nan = (np.full((3, 3), np.nan), np.full((3, 2), np.nan))
    lp = run_closed_loops([nan, (s.A, s.B)], s.A, s.B, cfg.mpc, s)
    assert lp.outcome == ["failed", "converged"] and np.isnan(lp.spectral_radius[0])
    assert lp.gains[0] is None and lp.gains[1].shape == (2, 3)


def test_certificate_is_a_proof_on_random_stable_loops():
    """A certified state never leaves the box along the affine loop (checked by simulation)."""
    rng = np.random.default_rng(3)
    hits = 0
    for _ in range(40):
        M = rng.normal(size=(3, 3))
        M *= 0.95 / spectral_radius(M)
        c, F = rng.normal(size=3) * 0.1, rng.normal(size=(4, 3))
        x = rng.normal(size=3) * 0.05
        bound = np.full(4, 2.0)
        ok, x_inf = certify(M, c, F, np.zeros(4), bound, x)
        if ok:
            hits += 1
            for _ in range(400):
                assert np.all(np.abs(F @ x) <= bound)
                x = M @ x + c
            assert np.linalg.norm(x - x_inf) < 1e-3
    assert hits > 5
    unstable = np.diag([1.01, 0.5, 0.2])
    assert certify(unstable, np.zeros(3), np.eye(3), np.zeros(3), np.ones(3), np.zeros(3))[0] is False
    assert lyapunov_batch(unstable[None])[1].tolist() == [False]


def test_complex_stability_radius_matches_a_fine_grid_and_small_gain_is_sound():
    rng = np.random.default_rng(0)
    for k in range(24):  # sizes 1-4, spectral radii up to 0.999 (sharp dips near the unit circle)
        n = 1 + k % 4
        M = rng.normal(size=(n, n))
        M *= (0.97 if k < 4 else rng.uniform(0.5, 0.999)) / spectral_radius(M)
        th = np.union1d(np.linspace(0, np.pi, 40001), np.abs(np.angle(np.linalg.eigvals(M))))
        fine = np.linalg.svd(np.exp(1j * th)[:, None, None] * np.eye(n) - M, compute_uv=False)[:, -1].min()
        r = complex_stability_radius(M)
        assert r <= fine + 1e-12 and r == pytest.approx(fine, rel=1e-6)
    assert complex_stability_radius(np.diag([1.2, 0.1])) == 0.0
    # the batch test agrees with the exact margin, and what it certifies is stable
    A, B = np.array([[1.0, 0.1], [0.0, 0.95]]), np.array([[0.0], [0.1]])
    Ah = A + rng.normal(size=(60, 2, 2)) * 0.02
    Bh = B + rng.normal(size=(60, 2, 1)) * 0.02
    K = np.tile(np.array([[2.0, 4.0]]), (60, 1, 1))
    fast = small_gain_holds(A, B, Ah, Bh, K)
    exact = np.array([np.less(*small_gain_margin(A, B, Ah[i], Bh[i], K[i])) for i in range(60)])
    assert (fast == exact).all() and 0 < fast.sum() < 60
    assert all(spectral_radius(A - B @ K[i]) < 1 for i in np.flatnonzero(fast))


def test_small_gain_holds_decides_as_the_exact_margin_near_the_radius():
    """Perturbations within 3 % of each loop's radius (where the bounds on arcs are least conclusive and the
    exact radius decides what the finest arcs leave open): the same decisions as the exact margin."""
    rng = np.random.default_rng(7)
    got = []
    for n, m in ((1, 1), (2, 1), (3, 2), (4, 1), (4, 2)):
        B = rng.normal(size=(n, m))
        for _ in range(16):
            M = rng.normal(size=(n, n))
            M *= rng.uniform(0.3, 0.999) / spectral_radius(M[None])[0]  # stable, dips near the circle too
            K = rng.normal(size=(1, m, n))
            Ah = M[None] + B @ K
            E = rng.normal(size=(n, n))
            A = Ah[0] + E / np.linalg.norm(E, 2) * complex_stability_radius(M) * rng.uniform(0.97, 1.03)
            fast = bool(small_gain_holds(A, B, Ah, B[None], K)[0])
            assert fast == np.less(*small_gain_margin(A, B, Ah[0], B, K[0])), (n, m)
            got.append(fast)
    assert 0 < sum(got) < len(got)


def test_the_stability_radius_is_at_most_the_distance_of_the_spectrum_to_the_circle():
    """The premise of small_gain_holds' first rejection: r_C(M) <= 1 - rho(M) for a stable M."""
    rng = np.random.default_rng(3)
    for _ in range(40):
        M = rng.normal(size=(3, 3))
        M *= rng.uniform(0.1, 0.95) / spectral_radius(M[None])[0]
        assert complex_stability_radius(M) <= 1.0 - spectral_radius(M[None])[0] + 1e-9


def test_controllability_margin():
    A = np.stack([np.diag([0.5, 0.7]), np.diag([0.5, 0.5])])
    B = np.stack([np.ones((2, 1)), np.ones((2, 1))])
    m = controllability_margin(A, B)
    assert m[0] > 1e-3 and m[1] < 1e-12  # equal eigenvalues with one input: not controllable
    assert np.isnan(controllability_margin(np.full((1, 2, 2), np.nan), np.ones((1, 2, 1)))[0])


def test_small_gain_holds_settles_normal_loops_by_their_eigenvalues_alone(monkeypatch):
    """For a normal M, r_C = 1 - rho(M) exactly, so Bauer-Fike's bound (cond(V) = 1) and the radial one
    decide every loop without a frequency sweep; the decisions are the exact margin's."""
    import qsid_core.control.stability_radius as sr

    def no_sweep(*a, **k):
        raise AssertionError("a frequency sweep was run")

    rng = np.random.default_rng(3)
    B = np.array([[0.0], [1.0]])
    K = np.zeros((1, 1, 2))
    cases = []
    for _ in range(20):
        c, s = np.cos(rng.uniform(0, np.pi)), rng.uniform(0.2, 0.9)
        Q, _ = np.linalg.qr(rng.normal(size=(2, 2)))
        M = Q @ np.array([[s * c, -s * np.sqrt(1 - c * c)], [s * np.sqrt(1 - c * c), s * c]]) @ Q.T  # normal
        E = rng.normal(size=(2, 2))
        cases.append((M, E / np.linalg.norm(E, 2) * (1 - s) * rng.choice([0.9, 1.1])))
    monkeypatch.setattr(sr, "_below_radius", no_sweep)
    got = [bool(small_gain_holds(M + E, B, M[None], B[None], K)[0]) for M, E in cases]
    monkeypatch.undo()
    exact = [np.less(*small_gain_margin(M + E, B, M, B, K[0])) for M, E in cases]
    assert got == exact and 0 < sum(got) < len(got)


def test_stability_radii_of_a_batch_are_each_matrix_radius():
    """The batch refines all dips at once; each radius is the one matrix's, unstable and non-finite give 0."""
    from qsid_core.control import complex_stability_radii, small_gain_margins

    rng = np.random.default_rng(11)
    Ms = []
    for _ in range(30):
        M = rng.normal(size=(3, 3))
        Ms.append(M * rng.uniform(0.2, 0.999) / spectral_radius(M))
    Ms += [np.diag([1.01, 0.2, 0.1]), np.full((3, 3), np.nan)]
    batch = complex_stability_radii(np.stack(Ms))
    assert batch == pytest.approx([complex_stability_radius(M) for M in Ms], rel=1e-12)
    assert batch[-2] == 0.0 and batch[-1] == 0.0 and np.all(batch[:-2] > 0)
    A, B = np.array([[1.0, 0.1], [0.0, 0.95]]), np.array([[0.0], [0.1]])
    Ah, Bh = A + rng.normal(size=(8, 2, 2)) * 0.02, B + rng.normal(size=(8, 2, 1)) * 0.02
    K = np.tile(np.array([[2.0, 4.0]]), (8, 1, 1))
    pert, rad = small_gain_margins(A, B, Ah, Bh, K)
    single = np.array([small_gain_margin(A, B, Ah[i], Bh[i], K[i]) for i in range(8)])
    np.testing.assert_allclose(np.stack([pert, rad], axis=1), single, rtol=1e-12)
