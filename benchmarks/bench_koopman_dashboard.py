"""How fast a dashboard tab showing a nonlinear plant answers, in-process (no server, no process pool).

* **data change**: a new data seed (nothing cached): seconds until the current b is drawn ("current"), until
  every b's models are ("models") and until every b's Koopman MPC loops are ("all");
* **b change**: another word length with everything cached: seconds until its frames are ready;
* **loops**: the Koopman MPC of one (b, estimator), each loop stepped alone (as before the loops were stepped in
  lockstep) against all of them in lockstep, on the same models: same verdicts, the time of each.

Interactive size of a nonlinear tab (``NL_INTERACTIVE``: Van der Pol, poly:3, 50 x 200, 5 realizations, LS and
BCLS, b = 1..16). CPU time is printed beside wall time (robust to other load on the machine).

Usage::

    python benchmarks/bench_koopman_dashboard.py [--repeat 3] [--save docs/perf/bench_koopman_dashboard.txt]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from app.frames.compute import iter_frames  # noqa: E402
from app.settings.values import (
    Values,  # noqa: E402
    nonlinear_values,  # noqa: E402
)
from qsid_core.control import run_koopman_loops  # noqa: E402


def _frames(values: Values, cache: dict) -> dict[str, float]:
    """Wall seconds until the current frame, the models frame and the last frame."""
    t0, out = time.perf_counter(), {}
    for f in iter_frames(values, cache):
        now = time.perf_counter() - t0
        out.setdefault("current", now)
        if f.stage == "curves":
            out.setdefault("models", now)
        out["all"] = now
    return out


def _loops(values: Values, cache: dict) -> tuple[float, float, bool]:
    """(each alone, lockstep) wall seconds of the loops at the current b by BCLS, and whether they agree."""
    frame = next(iter_frames(values, cache))
    ex = frame.ex
    assert ex is not None and ex.config.mpc is not None
    models = list(ex.models(frame.bits, "bcls").models)
    t = time.perf_counter()
    alone = [run_koopman_loops([m], ex.lifting, ex.system, ex.config.mpc, ex.config.radius) for m in models]
    t_alone = time.perf_counter() - t
    t = time.perf_counter()
    batch = run_koopman_loops(models, ex.lifting, ex.system, ex.config.mpc, ex.config.radius)
    t_batch = time.perf_counter() - t
    same = [a.outcome[0] for a in alone] == batch.outcome
    return t_alone, t_batch, same


def _main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--quick", action="store_true", help="a tiny size (smoke test)")
    a = p.parse_args(argv)
    v = nonlinear_values("van-der-pol", Values()).replace(bits=3)
    if a.quick:
        v = v.replace(trajectories=20, steps=50, realizations=2, mpc_steps=30, horizon=8)
    print(f"van-der-pol {v.lifting}, {v.trajectories} x {v.steps}, {v.realizations} realizations, LS + BCLS, b = 1..16")
    data, bchange, loops = [], [], []
    cache: dict = {}
    for r in range(a.repeat):
        c = time.process_time()
        d = _frames(v.replace(data_seed=100 + r), cache)
        d["cpu"] = time.process_time() - c
        data.append(d)
        bchange.append(_frames(v.replace(data_seed=100 + r, bits=7), cache))
        loops.append(_loops(v.replace(data_seed=100 + r), cache))
    med = lambda rows, k: statistics.median(x[k] for x in rows)  # noqa: E731
    print(
        f"data change: current b {med(data, 'current'):.2f} s, every b's models {med(data, 'models'):.2f} s, "
        f"every b's loops {med(data, 'all'):.2f} s (CPU {med(data, 'cpu'):.2f} s)"
    )
    print(f"b change (cached): current b {med(bchange, 'current'):.3f} s, all {med(bchange, 'all'):.3f} s")
    alone, batch = statistics.median(x[0] for x in loops), statistics.median(x[1] for x in loops)
    agree = all(x[2] for x in loops)
    print(
        f"loops at b = 3 (BCLS): each alone {alone:.2f} s, lockstep {batch:.2f} s "
        f"({alone / batch:.1f}x), same verdicts: {'yes' if agree else 'NO'}"
    )
    print(f"RESULT data={data} bchange={bchange} loops={loops}")
    return 0 if agree else 1


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; ``--save FILE`` also writes the printed output to FILE (header first)."""
    import _tee

    return int(_tee.run(_main, argv))


if __name__ == "__main__":
    raise SystemExit(main())
