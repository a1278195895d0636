"""A plant of your own: LS against BCLS at a few word lengths, with Theorem 1's prediction."""

from qsid_core import LTISystem, SweepConfig, run_sweep

plant = LTISystem("two-tank", A=[[0.95, 0.1], [0.0, 0.9]], B=[[0.0], [0.5]])
for est in ("ls", "bcls"):
    res = run_sweep(
        SweepConfig(system=plant, bits="2:6:2", realizations=5, trajectories=50, steps=400, estimator=est, mpc=None)
    )
    for b in res.bits:
        s = res.summary(b)
        print(f"{est:4s} b={b}: err_A {s.err_A.mean:.3e} (Theorem 1 for LS: {s.err_A_theory:.3e})")
