"""The engine's BLAS limit, and the dashboard's process-wide one."""

from __future__ import annotations

import json
import subprocess
import sys

from qsid_core.studies.executors import InlineExecutor

_PROBE = """
import numpy, scipy.linalg
from threadpoolctl import threadpool_info, threadpool_limits
from qsid_core.studies.executors import single_threaded_blas
def blas():
    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]
threadpool_limits(limits=2, user_api="blas")
before = blas()
inside = []
for _ in range(3):
    with single_threaded_blas():
        inside.append(blas())
after = blas()
from app.dashboard.lifecycle import one_blas_thread
one_blas_thread()
with single_threaded_blas():
    kept = blas()
import json
print(json.dumps([before, inside, after, blas(), kept]))
"""


def test_blas_limited_inside_restored_after_and_kept_where_set_once():
    # a fresh process: this one's BLAS limits are shared by every test
    out = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, check=True).stdout
    before, inside, after, once, kept = json.loads(out)
    if not before:
        return  # no BLAS library threadpoolctl can see: nothing to limit
    ones = [1] * len(before)
    assert before == [2] * len(before)
    assert inside == [ones] * 3, "one thread inside the block, on every call"
    assert after == before, "the previous limits restored after it"
    assert once == ones and kept == ones, "set once for the process, the engine's block leaves it alone"


def test_inline_executor_runs_when_asked():
    calls: list[int] = []
    fut = InlineExecutor().submit(lambda x: calls.append(x) or x * 2, 21)
    assert calls == []
    assert fut.result() == 42 and calls == [21]
