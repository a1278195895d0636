"""A small class on one real server (``benchmarks/bench_class.py``): 8 tabs changing word length, data, Q/R and
the saturated bound every 2-5 s for 60 s over websockets. Loose, non-timing checks: every tab gets an answer to
every change and ends on the final view of its last change, no tab dies, the server logs no traceback, and
memory (server plus workers) does not keep growing."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
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


def test_a_student_never_sends_the_value_a_slider_already_holds():
    """viser calls no callback for an unchanged value: such a send would never be answered (a false 'dead tab')."""
    import random

    import bench_class

    class FakeTab:
        def __init__(self):
            self.held = {"Q w": -1.0, "Q q": -1.0, "R thrust": 0.0, "input bound": 1.0}

        def labels(self, prefix):
            return sorted(k for k in self.held if k.startswith(prefix))

        def value(self, label):
            return self.held.get(label)

    st = bench_class.Student.__new__(bench_class.Student)
    st.saturated, st.tab, st.b, st.seed, st.bound = True, FakeTab(), 4, 0, 1.0
    for seed in range(200):
        st.rnd = random.Random(seed)
        for _ in range(20):
            kind, label, value = st.pick()
            if kind in ("Q/R", "saturated"):
                assert value != st.tab.held[label], (seed, label, value)
                st.tab.held[label] = value
    # the draws that would repeat a held value are redrawn, not skipped: a held -1.0 is drawn sometimes
    st.rnd = random.Random(0)
    st.rnd.uniform = lambda lo, hi, _v=iter([-1.0, -1.0, 0.5]): next(_v)
    st.rnd.choice = lambda xs: "Q/R" if "Q/R" in xs else ("Q w" if "Q w" in xs else xs[0])
    st.tab.held["Q w"] = -1.0
    assert st.pick() == ("Q/R", "Q w", 0.5)
