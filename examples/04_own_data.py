"""Your own recorded data (here: simulated and saved to a .npz first), identified at each word length."""

import tempfile
from pathlib import Path

import numpy as np

from qsid_core import QuantizerSpec, boeing747, identify_recorded, load_recorded, simulate

rec = simulate(boeing747(), 40, 300, seed=7)
with tempfile.TemporaryDirectory() as d:
    path = Path(d) / "recorded.npz"
    np.savez(path, x=rec.states, u=rec.inputs)
    data = load_recorded(path)
res = identify_recorded(data, "3,6,9", QuantizerSpec(dither="tpdf"), realizations=3)
for r in res.to_dict()["results"]:
    print(
        f"b={r['bits']}: LS err_A {r['ls']['err_A']['mean']:.3e}, BCLS err_A {r['bcls']['err_A']['mean']:.3e} "
        f"(against {res.reference})"
    )
