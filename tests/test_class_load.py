"""A small class on one real server (``benchmarks/bench_class.py``): 8 tabs changing word length, data, Q/R and
the saturated bound every 2-5 s for 60 s over websockets. Loose, non-timing checks: every tab gets an answer to
every change and ends on the final view of its last change, no tab dies, the server logs no traceback, and
memory (server plus workers) does not keep growing."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))


@pytest.mark.slow
def test_eight_tabs_for_a_minute():
    import bench_class

    out = bench_class.main(["--tabs", "8", "--duration", "60", "--every", "5", "--hang", "300"])
    assert out["tabs_died"] == [], out
    assert out["tabs_final_view"] == 8, out["not_final"]
    assert out["server_tracebacks"] == 0
    assert sum(k["n"] for k in out["per_kind"].values()) >= 8  # every tab made changes and got answers
    assert set(out["per_kind"]) >= {"word length", "data", "Q/R"}
    mem = out["memory_mb"]
    # not a limit on size, only on growth: the second half of the run holds no more than half again the first's
    assert out["memory_median_second_half_mb"] <= 1.5 * out["memory_median_first_half_mb"], mem
