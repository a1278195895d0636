#!/usr/bin/env python
"""``qsid bits`` against a ``qsid sweep`` of the same size, side by side in one run (target: <= 2x).

Each command runs as a whole process (``python -m app.cli ...``, wall clock from
process start to exit, the numba cache warm after a first untimed run of each, unless ``--no-warm``),
interleaved ``--repeats`` times, for each system. ``qsid bits`` runs the same
sweep plus the verdict of every closed loop on the true plant and the small-gain
tests; ``qsid sweep`` also judges its loops (the verdicts are part of every
sweep now), so the ratio is what the answer adds on top. The same pair is also
run with ``--verify-steps 0`` for the sweep (no stepping beyond the run) to show
what the verdicts themselves cost, and a sweep tracking ``sine:1:1:40`` under a
disturbance of 0.01 (the real loop: every step simulated with the reference preview
and the noise, verdicts from the noise-free law) against the plain sweep.

Prints a table with best/median per command and the ratio of medians; the last
line is ``RESULT {json}``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run(argv: list) -> float:
    t = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "app.cli", *argv, "-q", "--json"],
        cwd=ROOT,
        check=True,
        stdout=subprocess.DEVNULL,
        timeout=900,
    )
    return time.perf_counter() - t


def measure(system: str, size: list, repeats: int, warm: bool = True) -> dict:
    cmds = {
        "sweep": ["sweep", "--system", system, *size],
        "sweep --verify-steps 0": ["sweep", "--system", system, *size, "--verify-steps", "0"],
        "bits": ["bits", "--system", system, *size],
        "sweep tracking+disturbance": [
            "sweep",
            "--system",
            system,
            *size,
            "--reference",
            "sine:1:1:40",
            "--disturbance",
            "0.01",
        ],
    }
    for argv in cmds.values() if warm else ():  # warm the numba cache and the page cache, untimed
        _run(argv)
    times: dict = {k: [] for k in cmds}
    for _ in range(repeats):
        for k, argv in cmds.items():
            times[k].append(_run(argv))
    med = {k: statistics.median(v) for k, v in times.items()}
    return {
        "system": system,
        "best_s": {k: min(v) for k, v in times.items()},
        "median_s": med,
        "all_s": times,
        "ratio_bits_to_sweep": med["bits"] / med["sweep"],
        "ratio_sweep_to_unjudged": med["sweep"] / med["sweep --verify-steps 0"],
        "ratio_tracking_disturbance_to_sweep": med["sweep tracking+disturbance"] / med["sweep"],
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--systems", default="dc-motor,boeing747")
    p.add_argument("--quick", action="store_true", help="small data (a smoke run, not the paper-scale target)")
    p.add_argument(
        "--no-warm",
        dest="warm",
        action="store_false",
        help="skip the untimed first run of each command (a smoke run: the first timed run may include compiling)",
    )
    a = p.parse_args(argv)
    size = ["--bits", "1:4", "--realizations", "4", "--trajectories", "20", "--steps", "100"] if a.quick else []
    out = []
    print(f"{'system':10s} {'command':28s} {'best s':>8s} {'median s':>9s}")
    for s in a.systems.split(","):
        r = measure(s, size, a.repeats, a.warm)
        out.append(r)
        for k in r["median_s"]:
            print(f"{s:10s} {k:28s} {r['best_s'][k]:8.2f} {r['median_s'][k]:9.2f}")
        print(
            f"{s:10s} bits / sweep = {r['ratio_bits_to_sweep']:.2f} (target <= 2); "
            f"sweep / sweep without extra verdict steps = {r['ratio_sweep_to_unjudged']:.2f}; "
            f"tracking + disturbance sweep / plain sweep = {r['ratio_tracking_disturbance_to_sweep']:.2f}"
        )
    result = {"benchmark": "bench_bits", "quick": a.quick, "warm": a.warm, "repeats": a.repeats, "results": out}
    print("RESULT " + json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
