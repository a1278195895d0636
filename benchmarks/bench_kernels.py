"""The quantize-and-accumulate kernel: generic against the one generated for the system's size.

Times :func:`qsid_core.quantization.kernels.accumulate_chunk` over one realization of the
paper-scale data (200 runs x 1000 steps, chunks of ``qsid_core.quantization.moments.CHUNK_ROWS``
rows, all 16 word lengths in one pass) with the generic kernel and with
:func:`qsid_core.quantization.unrolled.kernel` for the preset systems' sizes, interleaved
(generic, generated, generic, ...) so both see the same machine load; prints
the median and spread of each and the ratio of the medians. The dither draws
are made once beforehand (not timed). Both compute the same sums (the largest
relative difference is printed).

Usage::

    python benchmarks/bench_kernels.py [--repeat 9] [--save docs/perf/bench_kernels.txt]
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

import numpy as np

from qsid_core.quantization import CHUNK_ROWS, kernels, unrolled
from qsid_core.quantization.sums import Sums

#: (name, channels p, states n): the preset systems' sizes
SIZES = (("dc-motor", 5, 3), ("boeing747", 6, 4), ("mass-spring-damper", 3, 2))


def _one(fn, y, u, scale, half, n, S1, runs) -> tuple[float, tuple]:
    out = Sums.zeros(scale.shape[0], scale.shape[1], n, runs).arrays()
    t = time.perf_counter()
    for s in range(0, len(y), CHUNK_ROWS):
        kernels.accumulate_chunk(y[s : s + CHUNK_ROWS], u[s : s + CHUNK_ROWS], scale, half, s, S1, *out, kernel=fn)
    return time.perf_counter() - t, out


def _main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=9, help="timed passes of each kernel per size (default 9)")
    a = ap.parse_args(argv)
    if not kernels.AVAILABLE:
        print(f"bench_kernels: compiled kernels unavailable ({kernels.REASON})")
        return 1
    runs, steps = 200, 1000
    S1 = steps + 1
    print(
        f"quantize-and-accumulate kernel, one realization of {runs} x {steps} samples, 16 word lengths, "
        f"{a.repeat} interleaved passes each · {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}"
    )
    print(
        f"{'system':<20} {'p':>2} {'n':>2}   generic [ms] median (min-max)   generated [ms] median (min-max)   ratio   max rel. diff"
    )
    for name, p, n in SIZES:
        rng = np.random.default_rng(0)
        y = rng.uniform(-0.45, 0.45, (runs * S1, p))
        u = rng.uniform(-0.5, 0.5, (runs * S1, p))
        bits = np.arange(1, 17)
        scale = np.repeat((2.0**bits - 2.0)[:, None], p, axis=1)
        half = np.repeat((2.0 ** (bits - 1))[:, None], p, axis=1)
        fast = unrolled.kernel(p, n)
        if fast is None:
            print(f"{name:<20} {p:>2} {n:>2}   no generated kernel: {unrolled.NOT_USED.get((p, n))}")
            continue
        _one(None, y, u, scale, half, n, S1, runs)  # compiled or loaded before timing
        _one(fast, y, u, scale, half, n, S1, runs)
        tg, tf = [], []
        for _ in range(a.repeat):
            t, ref = _one(None, y, u, scale, half, n, S1, runs)
            tg.append(t * 1000)
            t, got = _one(fast, y, u, scale, half, n, S1, runs)
            tf.append(t * 1000)
        diff = max(float(np.abs(x - z).max() / max(np.abs(x).max(), 1.0)) for x, z in zip(ref[:3], got[:3]))
        mg, mf = statistics.median(tg), statistics.median(tf)
        print(
            f"{name:<20} {p:>2} {n:>2}   {mg:8.1f} ({min(tg):.1f}-{max(tg):.1f}){'':>10}"
            f"{mf:8.1f} ({min(tf):.1f}-{max(tf):.1f}){'':>12}{mf / mg:5.2f}   {diff:.1e}"
        )
    return 0


def main(argv=None) -> int:
    """Run the benchmark; ``--save FILE`` also writes the printed output to FILE (header first)."""
    import _tee

    return _tee.run(_main, argv)


if __name__ == "__main__":
    sys.exit(main())
