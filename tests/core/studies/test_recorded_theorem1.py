"""``qsid identify`` on your own data gives Theorem 1's prediction from the data's own Sigma where its hypotheses
hold: the same numbers and the same verdicts as a sweep of the same data."""

import numpy as np

from app.cli.identify import format_table
from qsid_core import SweepConfig, get_system, identify_recorded, run_sweep
from qsid_core.plant.data import simulate


def test_recorded_prediction_is_the_sweeps():
    sysm = get_system("boeing747")
    cfg = SweepConfig(system=sysm, bits=(2, 4, 6, 8), realizations=3, trajectories=100, steps=500, mpc=None)
    res = run_sweep(cfg)
    d = simulate(sysm, 100, 500, seed=cfg.data_seed)
    rec = identify_recorded((d.states, d.inputs), cfg.bits, realizations=3, system=sysm)
    for b in cfg.bits:
        t, th, a = rec.theory[b], res.theory[b], res.assumptions[b]
        assert np.isclose(t["err_A"], th.err_A, rtol=1e-9) and np.isclose(t["err_B"], th.err_B, rtol=1e-9)
        assert (t["holds_A"], t["holds_B"]) == (a.theorem1_holds_A, a.theorem1_holds_B), b
    assert rec.theory[2]["holds_A"] and not rec.theory[8]["holds_A"]
    row = rec.to_dict()["results"][0]
    assert row["theorem1"]["err_A"] == rec.theory[2]["err_A"]
    text = format_table(rec.to_dict())
    assert f"{rec.theory[2]['err_A']:.3e}" in text and "Theorem 1 at b = 8: finite data for A^" in text


def test_an_integrator_has_no_prediction_and_says_why():
    sysm = get_system("dc-motor")
    d = simulate(sysm, 50, 200, seed=0)
    rec = identify_recorded((d.states, d.inputs), (4,), realizations=2)
    t = rec.theory[4]
    assert not t["holds_A"] and not t["holds_B"] and any("no limit" in w for w in t["why"])
