"""A paper-scale nonlinear (Koopman/EDMD) sweep against a paper-scale linear sweep, side by side.

* **nonlinear**: :func:`qsid_core.studies.run_koopman_sweep` on Van der Pol, 2000 runs x 100 steps,
  degree-3 monomials (10 features + 1 input), word lengths b = 1..16, 20 dither realizations;
* **linear**: :func:`qsid_core.run_sweep` on the DC motor, 200 runs x 1000 steps (the letter's
  200 000 samples), b = 1..16, 20 realizations.

Both identify only (no MPC closed loops: the hot path is the quantize-and-accumulate of the moments),
single process, one BLAS thread, for each estimator (``ls``; ``bcls``, which the nonlinear sweep
computes from the exact unbiased monomials as well), interleaved (linear, nonlinear, linear, ...) so both
see the same machine load; the median of ``--repeat`` runs is compared. The target is a
nonlinear sweep within 3x the linear one; the verdict line says whether this run met it.

Usage::

    python benchmarks/bench_koopman.py [--repeat 3] [--save docs/perf/bench_koopman.txt]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from qsid_core import SweepConfig, run_sweep  # noqa: E402
from qsid_core.studies import KoopmanConfig, run_koopman_sweep  # noqa: E402

BITS = tuple(range(1, 17))
TARGET = 3.0


def _timed(fn: Callable[[], object]) -> tuple[float, float]:
    """``(wall, cpu)`` seconds of ``fn()`` (CPU time of this process: robust to other load on the machine)."""
    w, c = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - w, time.process_time() - c


def _linear(estimator: str) -> tuple[float, float]:
    cfg = SweepConfig(
        system="dc-motor", trajectories=200, steps=1000, bits=BITS, realizations=20, estimator=estimator, mpc=None
    )
    return _timed(lambda: run_sweep(cfg))


def _nonlinear(estimator: str) -> tuple[float, float]:
    cfg = KoopmanConfig(
        system="van-der-pol",
        lifting="poly:3",
        estimator=estimator,
        bits=BITS,
        trajectories=2000,
        steps=100,
        realizations=20,
        mpc=None,
    )
    return _timed(lambda: run_koopman_sweep(cfg))


def _main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3, help="timed runs of each sweep (default 3)")
    a = ap.parse_args(argv)
    head = [
        f"paper-scale sweeps, identification only, 16 word lengths x 20 realizations, {a.repeat} interleaved runs "
        f"each · {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}",
        "linear: dc-motor 200 x 1000; nonlinear: van-der-pol 2000 x 100, poly:3 (10 features); "
        "medians, wall (CPU) seconds",
        f"{'estimator':<10} {'linear':>16} {'nonlinear':>18} {'ratio wall':>11} {'ratio CPU':>10}",
    ]
    print(*head, sep="\n")
    worst = 0.0
    for est in ("ls", "bcls"):
        _linear(est), _nonlinear(est)  # compile or load every kernel before timing
        tl, tn = [], []
        for _ in range(a.repeat):
            tl.append(_linear(est))
            tn.append(_nonlinear(est))
        lw, lc = (statistics.median(t[k] for t in tl) for k in (0, 1))
        nw, nc = (statistics.median(t[k] for t in tn) for k in (0, 1))
        worst = max(worst, nc / lc)
        line = f"{est:<10} {lw:>7.2f} ({lc:>6.2f}) {nw:>8.2f} ({nc:>6.2f}) {nw / lw:>11.2f} {nc / lc:>10.2f}"
        print(line)
    verdict = (
        f"target: nonlinear within {TARGET:g}x the linear sweep (CPU time): "
        f"{'met' if worst <= TARGET else 'NOT met'} (worst CPU ratio {worst:.2f})"
    )
    print(verdict)
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; ``--save FILE`` also writes the printed output to FILE (header first)."""
    import _tee

    return int(_tee.run(_main, argv))


if __name__ == "__main__":
    raise SystemExit(main())
