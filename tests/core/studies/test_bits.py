"""``qsid bits`` and :mod:`qsid_core.studies.bits`: the three word lengths, their rows, soundness, bad input."""

import dataclasses
import json
import threading

import numpy as np
import pytest

from app.cli import main
from qsid_core.control.mpc import MPCConfig
from qsid_core.errors import ConfigError
from qsid_core.plant.lti import LTISystem
from qsid_core.studies import (
    answer_from_rows,
    bits_needed,
    from_on,
    realized_small_gain,
    wilson_interval,
)
from qsid_core.studies.config import SweepConfig
from qsid_core.studies.sweep import run_sweep

SMALL_DATA = dict(trajectories=30, steps=100, realizations=4)

TINY = ["--bits", "1:4", "--realizations", "6", "--trajectories", "20", "--steps", "100"]

OTHER_SYSTEMS = {
    "stable": LTISystem("stable2", np.array([[0.9, 0.3], [0.0, 0.7]]), np.array([[0.0], [1.0]])),
    "unstable": LTISystem("unstable2", np.array([[1.05, 0.2], [0.0, 0.8]]), np.array([[0.1], [1.0]])),
    "integrator": LTISystem("double-integrator", np.array([[1.0, 1.0], [0.0, 1.0]]), np.array([[0.5], [1.0]])),
}


def test_wilson_interval_and_from_on():
    lo, hi = wilson_interval(50, 50)
    assert hi == 1.0 and lo == pytest.approx(0.9287, abs=1e-4)
    lo, hi = wilson_interval(2, 50)
    assert lo == pytest.approx(0.0110, abs=1e-4) and hi == pytest.approx(0.1346, abs=1e-4)
    assert np.isnan(wilson_interval(0, 0)[0])
    assert from_on([1, 2, 3, 4], [True, False, True, True]) == 3
    assert from_on([1, 2, 3], [True, True, False]) is None and from_on([1, 2], [True, True]) == 1


def _rows_agree(ans):
    """b_observed / b_robust / b_letter recomputed by hand from the rows."""
    t, g = ans.settings["target"], ans.settings["cost_gap"]
    rows = ans.rows
    obs = [r.stabilized_fraction >= t and r.cost_gap is not None and abs(r.cost_gap) <= g for r in rows]
    for name, ok in (
        ("b_observed", obs),
        ("b_robust", [r.robust for r in rows]),
        ("b_letter", [r.bound_self_consistent and r.bound_informative for r in rows]),
    ):
        got = getattr(ans, name)
        if got is None:
            assert not ok[-1], name
        else:
            k = [r.bits for r in rows].index(got)
            assert all(ok[k:]) and (k == 0 or not ok[k - 1]), name


@pytest.mark.parametrize("system", ["dc-motor", "boeing747"])
def test_answer_is_consistent_with_its_rows(system):
    ans = bits_needed(
        SweepConfig(system=system, bits=(1, 2, 3, 4, 6, 8, 10), realizations=12, trajectories=60, steps=300)
    )
    _rows_agree(ans)
    d = ans.to_dict()
    assert set(d) >= {"system", "settings", "b_observed", "b_robust", "b_letter", "rows", "sentence"}
    r0 = d["rows"][0]
    assert set(r0) >= {"bits", "stabilized_fraction", "stabilized_interval", "cost_gap"}
    lo, hi = r0["stabilized_interval"]
    assert lo <= r0["stabilized_fraction"] <= hi
    res = ans.result
    for row in ans.rows:  # the same counts as the sweep's own rows
        assert row.outcomes == res.summary(row.bits)["closed_loop_outcomes"]
    assert json.loads(json.dumps(d)) == d


@pytest.mark.slow
@pytest.mark.parametrize("name", ["dc-motor", "boeing747", *OTHER_SYSTEMS])
def test_small_gain_certificate_is_sound(name):
    """No realization whose own model error passes the small-gain test has an unstable true closed loop."""
    system = OTHER_SYSTEMS.get(name, name)
    big = name in ("dc-motor", "boeing747")
    res = run_sweep(
        SweepConfig(
            system=system,
            bits=(1, 2, 3, 4, 5, 6),
            realizations=30,
            trajectories=200 if big else 20,
            steps=300 if big else 40,
        )
    )
    certified = 0
    for b in res.bits:
        lp = res.loops[b]
        cert = realized_small_gain(res.identification[b], lp, res.system.A, res.system.B)
        certified += int(cert.sum())
        assert np.all(lp.spectral_radius[cert] < 1), (name, b)
        assert all(lp.outcome[r] != "diverged" for r in np.flatnonzero(cert))
    assert certified > 0


def test_answer_from_rows_and_bad_targets():
    rows = [
        {
            "bits": b,
            "closed_loop_outcomes": {"converged": c, "bounded": 10 - c, "diverged": 0, "failed": 0},
            "mpc_cost": {"mean": cost},
            "ultimate_bound": 1.0,
            "rho": 2.0,
            "bound_self_consistent": b > 2,
            "bound_informative": b > 3,
            "err_A": {"mean": 0.11},
            "err_A_theory": 0.1,
            "err_B": {"mean": 0.09},
            "err_B_theory": 0.1,
        }
        for b, c, cost in ((1, 2, 5.0), (2, 10, 1.05), (3, 10, 1.001), (4, 10, 1.0))
    ]
    ans = answer_from_rows("toy", {}, rows, 1.0, robust={1: (2.0, 1.0), 2: (0.5, 1.0), 3: (0.1, 1.0), 4: (0.1, 1.0)})
    assert (ans.b_observed, ans.b_robust, ans.b_letter) == (3, 2, 4)
    assert "from b = 3 on" in ans.sentence and "holds from b = 2 on" in ans.sentence and "from b = 4" in ans.sentence
    loose = answer_from_rows("toy", {}, rows, 1.0, target=0.2, cost_gap=10)
    assert loose.b_observed == 1 and loose.b_robust is None
    for kw, field in (
        (dict(target=0), "target"),
        (dict(target=1.5), "target"),
        (dict(cost_gap=-0.1), "cost gap"),
        (dict(target=float("nan")), "target"),
    ):
        with pytest.raises(ConfigError, match=field):
            answer_from_rows("toy", {}, rows, 1.0, **kw)
    with pytest.raises(ConfigError, match="MPC"):
        bits_needed(SweepConfig(mpc=None, bits=(2,)))
    with pytest.raises(ConfigError, match="verdicts"):
        bits_needed(SweepConfig(mpc=MPCConfig(verify_steps=None), bits=(2,)))


def test_cli_bits_table_and_json(capsys):
    assert main(["bits", *TINY, "-q"]) == 0
    out = capsys.readouterr().out
    assert "b_observed =" in out and "small gain" in out and "stabilized" in out
    assert out.strip().splitlines()[-1].startswith(("the MPC stabilizes", "in b = "))
    assert main(["bits", *TINY, "-q", "--json", "--target", "90%", "--cost-gap", "0.05"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["settings"]["target"] == 0.9 and d["settings"]["cost_gap"] == 0.05
    assert [r["bits"] for r in d["rows"]] == [1, 2, 3, 4]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--target", "0"], "argument --target: must be in (0, 1]"),
        (["--target", "1.2"], "argument --target: must be in (0, 1]"),
        (["--target", "lots"], "argument --target: must be a number like 0.95 or 95%"),
        (["--cost-gap=-0.5"], "argument --cost-gap: must be >= 0"),
        (["--cost-gap", "inf"], "argument --cost-gap: must be finite"),
        (["--verify-steps=-3"], "argument --verify-steps"),
    ],
)
def test_cli_bits_bad_input_is_one_line(capsys, args, message):
    assert main(["bits", *TINY, "-q", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err and "Traceback" not in err


def test_own_model_certificates_are_reused_across_input_bounds_and_match_a_fresh_count(monkeypatch):
    """The per-loop certificate is cached with its gain: a new input bound or start (same gains) tests no
    loop again, a new Q (new gains) tests them all, and every count equals :func:`realized_small_gain`'s."""
    import qsid_core.studies.bits_certificate as bc
    from qsid_core.studies import Experiment, certified_own_models

    tested = []
    real = bc.small_gain_holds

    me = threading.get_ident()

    def spy(A, B, Ah, Bh, K):
        if threading.get_ident() == me:  # (a dashboard of an earlier test may still finish a frame in its thread)
            tested.append(len(K))
        return real(A, B, Ah, Bh, K)

    monkeypatch.setattr(bc, "small_gain_holds", spy)
    cache: dict = {}
    base = SweepConfig(system="boeing747", bits=(4,), realizations=8, trajectories=40, steps=150)
    x0 = (20.0, 20.0, 0.0, 0.0)
    counts = []
    for mpc in (MPCConfig(x0=x0), MPCConfig(x0=x0, u_max=0.3), MPCConfig(x0=(5.0, 5.0, 0.0, 0.0), u_max=0.2)):
        ex = Experiment(dataclasses.replace(base, mpc=mpc), cache=cache)
        counts.append(certified_own_models(ex, 4, "ls"))
        monkeypatch.setattr(bc, "small_gain_holds", real)  # the fresh count is not one of the cached tests
        fresh = realized_small_gain(ex.identification(4, "ls"), ex.closed_loops(4, "ls"), ex.system.A, ex.system.B)
        assert counts[-1] == int(fresh.sum())
        monkeypatch.setattr(bc, "small_gain_holds", spy)
    assert len(tested) == 1 and tested[0] > 0  # the gains did not change with the bound or the start
    ex = Experiment(dataclasses.replace(base, mpc=MPCConfig(x0=x0, Q=(10.0, 1.0, 1.0, 1.0))), cache=cache)
    certified_own_models(ex, 4, "ls")
    assert len(tested) == 2 and tested[1] > 0  # new weights, new gains: tested again


@pytest.mark.parametrize("system", ["dc-motor", *OTHER_SYSTEMS])
def test_predicted_small_gains_in_one_batch_match_an_independent_computation(system):
    """Theorem 1's model per b: scipy's DARE, a plain Riccati recursion for the MPC's first gain, and the
    stability radius on a fine grid of the unit circle give the batch's (perturbation, radius) per b."""
    import scipy.linalg as sla

    from qsid_core.studies import predicted_small_gain, predicted_small_gains
    from qsid_core.studies.experiment import Experiment

    bits = (1, 2, 3, 4, 6, 8)
    ex = Experiment(SweepConfig(system=OTHER_SYSTEMS.get(system, system), bits=bits, mpc=MPCConfig(), **SMALL_DATA))
    got = predicted_small_gains(ex, bits)
    assert list(got) == list(bits)
    w = MPCConfig().resolve(ex.system)
    A, B, n = ex.system.A, ex.system.B, ex.system.n
    th = np.union1d(np.linspace(0.0, np.pi, 20001), np.linspace(0.0, np.pi, 7))
    finite = 0
    for b in bits:
        G = ex.theory(b).G_pred
        Ah, Bh = G[:, :n], G[:, n:]
        try:
            P = sla.solve_discrete_are(Ah, Bh, w.Q, w.R)
        except (np.linalg.LinAlgError, ValueError):
            assert got[b] == (np.inf, 0.0)
            continue
        for _ in range(MPCConfig().horizon - 1):  # P_1 of the recursion from the terminal weight P_N = P
            K = np.linalg.solve(w.R + Bh.T @ P @ Bh, Bh.T @ P @ Ah)
            P = w.Q + Ah.T @ P @ Ah - (Bh.T @ P @ Ah).T @ K
        K = np.linalg.solve(w.R + Bh.T @ P @ Bh, Bh.T @ P @ Ah)
        M = Ah - Bh @ K
        pert = np.linalg.norm((A - Ah) - (B - Bh) @ K, 2)
        rad = np.linalg.svd(np.exp(1j * th)[:, None, None] * np.eye(n) - M, compute_uv=False)[:, -1].min()
        if np.abs(np.linalg.eigvals(M)).max() >= 1:
            rad = 0.0
        assert got[b][0] == pytest.approx(pert, rel=1e-8), b
        assert got[b][1] <= rad + 1e-12 and got[b][1] == pytest.approx(rad, rel=1e-6, abs=1e-12), b
        finite += 1
    assert finite >= 3
    # one word length at a time, in a fresh experiment: the same numbers
    one = Experiment(ex.config)
    for b in bits:
        assert predicted_small_gain(one, b) == pytest.approx(got[b], rel=1e-12)
