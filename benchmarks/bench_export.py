"""Static export in a local headless Chromium: seconds per figure, one browser per figure vs one for all.

``python benchmarks/bench_export.py [--figures N]`` draws the error view of two small sweeps N times
as PNG, SVG and PDF, first with :func:`app.figures.save_figure` per file (a Chromium started for
each), then with :func:`app.figures.export.save_figures` (one Chromium for all), and prints the
wall-clock seconds of both and their ratio, with the files' sizes. Both runs write the same files
(checked: same PNG size in pixels, every file non-empty). Needs /usr/bin/chromium and playwright.
"""

from __future__ import annotations

import argparse
import json
import struct
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def _png_size(p: Path) -> tuple:
    return struct.unpack(">II", p.read_bytes()[16:24])


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--figures", type=int, default=2, help="figures per format (default 2)")
    a = ap.parse_args(argv)

    from app.figures import plot_results, save_figure
    from app.figures.export import chromium_path, save_figures, why_no_browser
    from qsid_core import SweepConfig, run_sweep

    why = why_no_browser(chromium_path())
    if why:
        print(f"blocked: {why}")
        return {"blocked": why}
    small = dict(system="boeing747", bits=(2, 3, 4, 5, 6), trajectories=20, steps=200, realizations=2, mpc=None)
    fig = plot_results(*(run_sweep(SweepConfig(estimator=e, **small)) for e in ("ls", "bcls")))
    out = {}
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        names = [f"f{i}.{fmt}" for i in range(a.figures) for fmt in ("png", "svg", "pdf")]
        (d / "each").mkdir()
        (d / "once").mkdir()
        t0 = time.perf_counter()
        for n in names:
            save_figure(fig, d / "each" / n)
        t1 = time.perf_counter()
        save_figures([(fig, d / "once" / n) for n in names])
        t2 = time.perf_counter()
        for n in names:
            assert (d / "each" / n).stat().st_size > 0 and (d / "once" / n).stat().st_size > 0
            if n.endswith(".png"):
                assert _png_size(d / "each" / n) == _png_size(d / "once" / n)
        sizes = {fmt: (d / "once" / f"f0.{fmt}").stat().st_size for fmt in ("png", "svg", "pdf")}
    out = {
        "files": len(names),
        "one_chromium_per_file_s": round(t1 - t0, 2),
        "one_chromium_for_all_s": round(t2 - t1, 2),
        "ratio": round((t1 - t0) / (t2 - t1), 2),
        "bytes": sizes,
    }
    print(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
