"""Where a dashboard change spends its CPU time: identification, closed loops, bounds, figures, serialisation.

:class:`Breakdown` wraps the engine's and the dashboard's entry points in this process
and charges each thread's CPU time (``time.thread_time``) to the innermost category
running on that thread (a closed loop that first identifies its models charges the
identification to "identification"). What no category covers (frames, cache,
summary, 3-D scene, thread hand-over) is "other". Run in-process (``--workers 0``):
a process pool's workers are not seen.
"""

from __future__ import annotations

import threading
import time
from collections import defaultdict

CATEGORIES = {
    "identification (quantize + estimate)": [
        ("qsid_core.studies.experiment", "Experiment", "moments"),
        ("qsid_core.studies.experiment", "Experiment", "identification"),
    ],
    "closed loops (MPC + verdicts)": [
        ("qsid_core.studies.experiment", "Experiment", "closed_loops"),
        ("qsid_core.studies.experiment", "Experiment", "closed_loops_many"),
        ("qsid_core.studies.experiment", "Experiment", "true_model_loop"),
    ],
    "bounds and assumptions (theory)": [
        ("qsid_core.studies.experiment", "Experiment", "theory"),
        ("qsid_core.studies.experiment", "Experiment", "realized_bound"),
        ("qsid_core.studies.experiment", "Experiment", "assumptions"),
    ],
    "figure building": [("app.frames.render", "Renderer", "render")],
    "serialisation (figure JSON)": [("app.figures.raw", "Wire", "to_json")],
}


class Breakdown:
    """CPU seconds per category while installed (a context manager)."""

    def __init__(self):
        self.cpu: dict = defaultdict(float)
        self._local = threading.local()
        self._saved: list = []

    def _wrap(self, f, cat: str):
        def wrapped(*a, **k):
            st = self._local.__dict__.setdefault("stack", [])
            now = time.thread_time()
            if st:  # the caller's segment ends here
                self.cpu[st[-1][0]] += now - st[-1][1]
            st.append([cat, now])
            try:
                return f(*a, **k)
            finally:
                now = time.thread_time()
                c, t = st.pop()
                self.cpu[c] += now - t
                if st:
                    st[-1][1] = now

        return wrapped

    def __enter__(self) -> Breakdown:
        import importlib

        for cat, targets in CATEGORIES.items():
            for mod, cls, name in targets:
                owner = getattr(importlib.import_module(mod), cls)
                f = owner.__dict__[name]
                self._saved.append((owner, name, f))
                setattr(owner, name, self._wrap(f, cat))
        return self

    def __exit__(self, *exc) -> None:
        for owner, name, f in reversed(self._saved):
            setattr(owner, name, f)
        self._saved.clear()

    def reset(self) -> None:
        self.cpu.clear()


def line(b: Breakdown, total_cpu: float, changes: int) -> str:
    """One printed line: CPU ms per change in each category, and the share of the total."""
    parts = []
    covered = 0.0
    for cat in CATEGORIES:
        v = b.cpu.get(cat, 0.0)
        covered += v
        parts.append(f"{cat} {1000 * v / changes:.0f} ({100 * v / max(total_cpu, 1e-9):.0f}%)")
    other = max(total_cpu - covered, 0.0)
    parts.append(f"other {1000 * other / changes:.0f} ({100 * other / max(total_cpu, 1e-9):.0f}%)")
    return " · ".join(parts)
