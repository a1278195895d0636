"""The nonlinear sweeps' headline claims (docs/science.rst, "Nonlinear plants"), on the paper-scale data.

Full training data (2000 runs x 100 steps, ``poly:3``, subtractive dither, guard band, per-channel range),
9 dither realizations (one Koopman MPC loop per realization's model, from the plant's x0) and only the word
lengths a claim is about. The margins were checked on six (data seed, dither seed) pairs: the error ratio at
b = 3 was 49..70 (asserted >= 10), at b = 4 70..79; Van der Pol at b = 2 converged 0/9 (LS) against 5..8/9
(BCLS); Duffing at b = 3 0/9 against 9/9; the pendulum at b = 2 9/9 against 5..9/9.
"""

from __future__ import annotations

import pytest

from qsid_core.studies import KoopmanConfig, run_koopman_sweep

pytestmark = pytest.mark.slow

BASE = dict(trajectories=2000, steps=100, realizations=9, data_seed=0, dither_seed=1)


_ROWS: dict = {}


def _row(system: str, estimator: str, b: int) -> dict:
    if (system, estimator, b) not in _ROWS:
        r = run_koopman_sweep(KoopmanConfig(system=system, estimator=estimator, bits=(b,), **BASE))
        _ROWS[system, estimator, b] = r.rows[0]
    return _ROWS[system, estimator, b]


def _converged(system: str, estimator: str, b: int) -> int:
    """Loops ending within the convergence radius (the issue's count; the verdict "converged" is stricter)."""
    return int(_row(system, estimator, b)["within_radius"])


def test_de_biased_edmd_is_tens_of_times_closer_to_the_unquantized_edmd_on_van_der_pol():
    err = {}
    for est in ("ls", "bcls"):
        r = run_koopman_sweep(KoopmanConfig(system="van-der-pol", estimator=est, bits=(3, 4), mpc=None, **BASE))
        err[est] = [row["err_G"]["mean"] for row in r.rows]
    assert 1.0 < err["ls"][0] < 1.3 and 0.35 < err["ls"][1] < 0.45  # LS's bias: 1.14 and 0.40 in the issue
    assert err["bcls"][0] * 10 <= err["ls"][0]
    assert err["bcls"][1] * 10 <= err["ls"][1]


def test_koopman_mpc_from_ls_fails_where_the_de_biased_model_converges():
    assert _converged("van-der-pol", "ls", 2) == 0
    assert _converged("van-der-pol", "bcls", 2) >= 3
    assert _converged("duffing", "ls", 3) <= 1
    assert _converged("duffing", "bcls", 3) >= 7


def test_pendulum_at_two_bits_the_steady_biased_ls_converges_at_least_as_often_as_the_noisy_de_biased():
    assert _converged("pendulum", "ls", 2) >= _converged("pendulum", "bcls", 2)


def _loops(system: str, estimator: str, b: int, radius: float, realizations: int, cache: dict):
    """The engine's loops at ``b`` judged with ``radius`` (the models are shared through ``cache``)."""
    from qsid_core.studies import KoopmanExperiment

    base = {**BASE, "realizations": realizations}
    ex = KoopmanExperiment(KoopmanConfig(system=system, estimator=estimator, bits=(b,), radius=radius, **base), cache)
    return ex.loops(b, estimator)


def test_the_radius_moves_the_pendulums_count_but_no_radius_fits_the_issues_three_counts():
    """science.rst's note (loops ending within the radius): BCLS 16/20 at radius 0.1 and 10/20 at 0.05 (8/9 and 6/9 of the first 9), LS 20/20 at
    both; the issue's pendulum 9/9 against 3/9 needs a radius in [0.0327, 0.034), where Van der Pol's BCLS
    converges 2/9 (issue 6/9); at 0.05 it converges 4/9; Duffing's BCLS 9/9 at either."""
    import numpy as np

    def final(lp) -> np.ndarray:
        return np.linalg.norm(lp.states[:, -1, :], axis=1)

    cache: dict = {}
    counts = {}
    for est in ("ls", "bcls"):
        for r in (0.1, 0.05):
            within = _loops("pendulum", est, 2, r, 20, cache).within_radius
            counts[est, r] = (int(within.sum()), int(within[:9].sum()))
    assert counts["ls", 0.1] == counts["ls", 0.05] == (20, 9)
    assert counts["bcls", 0.1] == (16, 8) and counts["bcls", 0.05] == (10, 6)
    ls9, bc9 = (
        final(_loops("pendulum", "ls", 2, 0.1, 20, cache))[:9],
        final(_loops("pendulum", "bcls", 2, 0.1, 20, cache))[:9],
    )
    lo, hi = ls9.max(), np.sort(bc9)[3]  # LS 9/9 and BCLS 3/9 for a radius in [lo, hi)
    assert 0.0326 < lo < hi < 0.0341, (lo, hi)
    vdp = final(_loops("van-der-pol", "bcls", 2, 0.1, 9, {}))
    assert int(np.sum(vdp <= lo)) == int(np.sum(vdp < hi)) == 2 and int(np.sum(vdp <= 0.05)) == 4
    duff = final(_loops("duffing", "bcls", 3, 0.1, 9, {}))
    assert duff.max() < 0.02


def test_pendulum_bcls_at_two_bits_settles_at_an_offset_bounded_not_converged():
    # the CLI's defaults (20 realizations): qsid sweep --system pendulum --lifting poly:3 --estimator bcls --bits 2
    cfg = KoopmanConfig(system="pendulum", estimator="bcls", bits=(2,), **{**BASE, "realizations": 20})
    res = run_koopman_sweep(cfg)
    row = res.rows[0]
    assert row["closed_loop_outcomes"]["converged"] == 0 and row["closed_loop_outcomes"]["bounded"] >= 12
    assert 0.045 <= row["settled_offset"]["median"] <= 0.065  # the issue: 0.05-0.06 (0.052 measured)
    assert row["within_radius"] >= 12  # the old count (16 of 20 measured) is kept apart
    assert res.reference_outcome == "bounded" and 0 < res.reference_offset < row["settled_offset"]["median"]
