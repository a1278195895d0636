"""A paper-scale nonlinear (Koopman/EDMD) sweep against a paper-scale linear sweep, side by side.

* **nonlinear**: :func:`qsid_core.studies.run_koopman_sweep` on Van der Pol, 2000 runs x 100 steps,
  degree-3 monomials (10 features + 1 input), word lengths b = 1..16, 20 dither realizations;
* **linear**: :func:`qsid_core.run_sweep` on the DC motor (3 states, 2 inputs), 200 runs x 1000 steps,
  b = 1..16, 20 realizations.

Both have 200 000 samples, both are whole sweeps without the MPC closed loops (what ``qsid sweep
--no-mpc`` runs): the data, the quantized moments of every realization and word length, the models and
their errors, and each sweep's own extras (linear: Theorem 1, the a-posteriori bound and the assumption
checks; nonlinear: the unquantized EDMD, the prediction error of every model on held-out runs and, for
LS, the large-data limit). Each runs in this one process (the engine's in-process executor, numba kernels
single-threaded, BLAS limited to one thread), so its CPU time (``time.process_time``) is all the work it
did, whatever else runs on the machine; wall time is printed too. For each estimator the two sweeps run
interleaved (linear, nonlinear, linear, ...) so they see the same load, ``--repeat`` times after one
untimed run that compiles or loads every kernel, and the medians are compared. The target is a nonlinear
sweep within 3x the linear one (CPU time); the verdict line says whether this run met it.

A last row times the quantized moments alone (the hot path: every realization x word length, plain and
de-biased), the linear sweep's ``moments_task`` against
:func:`qsid_core.identification.quantized_lifted_realizations`, on data simulated beforehand.

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

import numpy as np  # noqa: E402

from qsid_core import SweepConfig, run_sweep  # noqa: E402
from qsid_core.identification import quantized_lifted_realizations  # noqa: E402
from qsid_core.plant import simulate_nonlinear  # noqa: E402
from qsid_core.studies import Experiment, KoopmanConfig, run_koopman_sweep  # noqa: E402
from qsid_core.studies.identification_stage import moments_task  # noqa: E402

BITS = tuple(range(1, 17))
REALIZATIONS = 20
TARGET = 3.0


def _timed(fn: Callable[[], object]) -> tuple[float, float]:
    """``(wall, cpu)`` seconds of ``fn()`` (CPU time of this process: robust to other load on the machine)."""
    w, c = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - w, time.process_time() - c


def _linear_cfg(estimator: str) -> SweepConfig:
    return SweepConfig(
        system="dc-motor",
        trajectories=200,
        steps=1000,
        bits=BITS,
        realizations=REALIZATIONS,
        estimator=estimator,
        mpc=None,
    )


def _nonlinear_cfg(estimator: str) -> KoopmanConfig:
    return KoopmanConfig(
        system="van-der-pol",
        lifting="poly:3",
        estimator=estimator,
        bits=BITS,
        trajectories=2000,
        steps=100,
        realizations=REALIZATIONS,
        mpc=None,
    )


def _linear(estimator: str) -> tuple[float, float]:
    cfg = _linear_cfg(estimator)
    return _timed(lambda: run_sweep(cfg))


def _nonlinear(estimator: str) -> tuple[float, float]:
    cfg = _nonlinear_cfg(estimator)
    return _timed(lambda: run_koopman_sweep(cfg))


def _moments_only() -> tuple[Callable[[], object], Callable[[], object]]:
    """The two moment computations, on data simulated beforehand (not timed)."""
    lin = _linear_cfg("bcls")
    prep = Experiment(lin).prepared
    lin_seeds = np.random.SeedSequence(lin.dither_seed).spawn(lin.realizations)
    nl = _nonlinear_cfg("bcls")
    data = simulate_nonlinear(nl.plant(), nl.trajectories, nl.steps, nl.data_seed, nl.input_amplitude)
    lifting = nl.dictionary()
    seeds = np.random.SeedSequence(nl.dither_seed).spawn(nl.realizations)

    def linear() -> object:
        return moments_task(prep, BITS, lin.quantizer, lin_seeds, lin.input_bits, lin.state_bits)

    def nonlinear() -> object:
        return quantized_lifted_realizations(data, lifting, BITS, nl.quantizer, seeds, True)

    return linear, nonlinear


def _row(name: str, lin: list[tuple[float, float]], non: list[tuple[float, float]]) -> tuple[str, float]:
    lw, lc = (statistics.median(t[k] for t in lin) for k in (0, 1))
    nw, nc = (statistics.median(t[k] for t in non) for k in (0, 1))
    line = f"{name:<10} {lw:>7.2f} ({lc:>6.2f}) {nw:>8.2f} ({nc:>6.2f}) {nw / lw:>11.2f} {nc / lc:>10.2f}"
    return line, nc / lc


def _main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3, help="timed runs of each sweep (default 3)")
    a = ap.parse_args(argv)
    head = [
        f"paper-scale sweeps without closed loops (--no-mpc), 200 000 samples, b = 1..16, {REALIZATIONS} "
        f"realizations · {a.repeat} interleaved runs each · {os.cpu_count()} CPUs, load average "
        f"{os.getloadavg()[0]:.2f}",
        "linear: dc-motor 200 x 1000 (data, moments, models, Theorem 1, bounds, assumption checks)",
        "nonlinear: van-der-pol 2000 x 100, poly:3 = 10 features + 1 input (data, moments, models, unquantized "
        "EDMD, prediction errors, LS: large-data limit)",
        "one process each, CPU = time.process_time (no workers, one BLAS thread); medians, wall (CPU) seconds",
        f"{'sweep':<10} {'linear':>16} {'nonlinear':>18} {'ratio wall':>11} {'ratio CPU':>10}",
    ]
    print(*head, sep="\n")
    worst = 0.0
    for est in ("ls", "bcls"):
        _linear(est), _nonlinear(est)  # compile or load every kernel before timing
        tl, tn = [], []
        for _ in range(a.repeat):
            tl.append(_linear(est))
            tn.append(_nonlinear(est))
        line, ratio = _row(est, tl, tn)
        worst = max(worst, ratio)
        print(line)
    lin, non = _moments_only()
    lin(), non()
    ml, mn = [], []
    for _ in range(a.repeat):
        ml.append(_timed(lin))
        mn.append(_timed(non))
    print(_row("moments", ml, mn)[0] + "   (quantized moments alone, LS and de-biased, data prepared)")
    verdict = (
        f"target: nonlinear sweep within {TARGET:g}x the linear one (CPU time): "
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
