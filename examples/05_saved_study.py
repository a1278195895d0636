"""Save a study, read it back, re-run it: the same numbers, bit for bit."""

import json
import tempfile
from pathlib import Path

import numpy as np

from qsid_core import SweepConfig, load_result, run_sweep

res = run_sweep(
    SweepConfig(system="dc-motor", bits="2:5", realizations=3, trajectories=20, steps=200, mpc=None, noise=0.01)
)
with tempfile.TemporaryDirectory() as d:
    path = Path(d) / "study.json"
    path.write_text(json.dumps(res.to_dict()))
    back = load_result(path)
print(back)
again = run_sweep(back.config)
same = all(np.array_equal(again.identification[b].err_A, res.identification[b].err_A) for b in res.bits)
print(f"saved with qsid {back.version}; re-run identical: {same}")
assert same
