#!/usr/bin/env python
"""What the dither kinds and the per-channel word lengths cost in the fused moments kernel.

Identification per (b, realization) -- quantized moments + LS -- on the dc-motor at paper scale
(200 x 1000), for every dither kind (subtractive, tpdf, rpdf, none) and for exact inputs, with the
compiled kernel and with the numpy reference. ``tpdf`` draws two uniforms per entry, so its extra
cost is one more block of random numbers; the quantization loop itself is the same.

Also checks that the two engines give the same Gram matrices for every row (max relative difference).
Figures are measured, best and median of ``--repeats``; the last line is ``RESULT {json}``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np

from qsid_core import Experiment, QuantizerSpec, SweepConfig, identify, quantized_moments
from qsid_core.quantization import kernels

PAPER = dict(trajectories=200, steps=1000, bits=tuple(range(1, 17)))
QUICK = dict(trajectories=10, steps=200, bits=(2, 6, 10))
ROWS = (
    ("subtractive", "subtractive", None),
    ("tpdf", "tpdf", None),
    ("rpdf", "rpdf", None),
    ("none", "none", None),
    ("subtractive, inputs exact", "subtractive", "exact"),
)


def _time(prep, bits, spec, seeds, engine, input_bits) -> tuple[float, list]:
    t0 = time.perf_counter()
    last = []
    for ss in seeds:
        rng = np.random.default_rng(ss) if spec.dither != "none" else None
        last = quantized_moments(prep, bits, spec, rng, engine=engine, input_bits=input_bits)
        for mo in last:
            identify(mo, "ls")
    return time.perf_counter() - t0, last


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small scale, one repeat (smoke test)")
    ap.add_argument("--repeats", type=int, default=None, help="repeats (default 3; quick 1)")
    ap.add_argument("--realizations", type=int, default=None, help="realizations timed (default 4; quick 2)")
    args = ap.parse_args(argv)
    scale = QUICK if args.quick else PAPER
    reps = args.repeats or (1 if args.quick else 3)
    nr = args.realizations or (2 if args.quick else 4)
    bits = list(scale["bits"])
    seeds = np.random.SeedSequence(1).spawn(nr)
    per = len(bits) * nr
    engines = ("numba", "numpy") if kernels.AVAILABLE else ("numpy",)
    out: dict = dict(
        benchmark="bench_dither",
        quick=bool(args.quick),
        cores=os.cpu_count(),
        numba=kernels.AVAILABLE,
        trajectories=scale["trajectories"],
        steps=scale["steps"],
        bits=bits,
        realizations=nr,
        rows={},
    )
    print(
        f"dither kinds in the fused moments kernel: dc-motor {scale['trajectories']} x {scale['steps']}, "
        f"{len(bits)} word lengths x {nr} realizations, ms per (b, realization); {os.cpu_count()} shared cores"
    )
    print(f"  {'':<28}" + "".join(f"{e + ' best':>13}{'median':>9}" for e in engines) + f"{'engines agree':>15}")
    for label, dither, ib in ROWS:
        spec = QuantizerSpec(dither=dither)
        prep = Experiment(
            SweepConfig(
                system="dc-motor",
                mpc=None,
                quantizer=spec,
                realizations=1,
                trajectories=scale["trajectories"],
                steps=scale["steps"],
            )
        ).prepared
        row, moms = {}, {}
        for e in engines:
            _time(prep, bits[:1], spec, seeds[:1], e, ib)  # warm up (compile or cache load)
            ts = []
            for _ in range(reps):
                t, moms[e] = _time(prep, bits, spec, seeds, e, ib)
                ts.append(t / per)
            row[e] = dict(best=min(ts), median=statistics.median(ts))
        diff = max(
            float(np.abs(a.PP - b.PP).max() / np.abs(b.PP).max()) for a, b in zip(moms[engines[0]], moms[engines[-1]])
        )
        row["max_rel_diff_PP"] = diff
        out["rows"][label] = row
        print(
            f"  {label:<28}"
            + "".join(f"{row[e]['best'] * 1e3:13.2f}{row[e]['median'] * 1e3:9.2f}" for e in engines)
            + f"{diff:15.1e}"
        )
    base = out["rows"]["subtractive"][engines[0]]["best"]
    for label in out["rows"]:
        out["rows"][label]["ratio_to_subtractive"] = out["rows"][label][engines[0]]["best"] / base
    print(
        "  cost relative to subtractive ("
        + engines[0]
        + "): "
        + ", ".join(f"{k} {v['ratio_to_subtractive']:.2f}x" for k, v in out["rows"].items())
    )
    print("RESULT " + json.dumps(out))
    return out


if __name__ == "__main__":
    main()
