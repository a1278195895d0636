"""Several results on one figure: LS and BCLS with subtractive and TPDF dither, saved as PNG and HTML.

Usage: ``python examples/06_plot_results.py [DIR]`` (default: a new temporary folder). The PNG is drawn
offline by a local headless Chromium (/usr/bin/chromium); without it the figure is written as HTML and
the script says why.
"""

import sys
import tempfile
from pathlib import Path

from app.figures import plot_results, save_figure
from qsid_core import QuantizerSpec, SweepConfig, run_sweep

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="qsid-figures-"))
out.mkdir(parents=True, exist_ok=True)

results = [
    run_sweep(
        SweepConfig(
            system="boeing747",
            bits=tuple(range(2, 9)),
            quantizer=QuantizerSpec(dither=dither, range_mode="fixed", fixed_range=(-20, 20)),
            estimator=est,
            realizations=3,
            trajectories=50,
            steps=300,
            mpc=None,
        )
    )
    for dither in ("subtractive", "tpdf")
    for est in ("ls", "bcls")
]
for r in results:  # the numbers behind the curves
    s = r.summary(3)
    print(f"{r.config.quantizer.dither:11s} {r.config.estimator:4s}  b = 3: err_A {s.err_A.mean:.3f}")

fig = plot_results(*results, view="error")
for name in ("errors.png", "errors.html"):
    saved = save_figure(fig, out / name)
    print(f"wrote {saved.path}" + (f"  ({saved.note})" if saved.note else ""))
