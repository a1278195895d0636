#!/usr/bin/env python
"""A long fuzz run of the engine's public API: what every call gave, per entry point.

Runs the hypothesis tests of ``tests/core/test_engine_fuzz.py`` and ``tests/core/test_engine_inputs.py``
with ``--examples`` randomized examples each (the suite runs a fixed, small set) and prints, per entry
point, how many calls gave a result, an engine error (a ``QsidError``: fine), another exception, a hang
(no answer within the tests' ``HANG_S``) or an unflagged NaN. The last line is ``RESULT {json}``; the
exit status is 0 when no call gave another exception, a hang or a NaN.

    python benchmarks/fuzz_engine.py [--examples 2000] [--save docs/perf/fuzz_engine.txt]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TESTS = ["tests/core/test_engine_fuzz.py", "tests/core/test_engine_inputs.py"]
BAD = ("other exception", "hang", "unflagged NaN")
COLUMNS = ("result", "engine error", *BAD)


def run(examples: int, keyword: str = "fuzz") -> tuple[dict, str, float]:
    """Run the fuzz tests; returns (counts per entry point, pytest's last line, seconds)."""
    with tempfile.TemporaryDirectory() as tmp:
        report = Path(tmp) / "fuzz.json"
        env = dict(
            os.environ,
            QSID_FUZZ_EXAMPLES=str(examples),
            QSID_FUZZ_RANDOM="1",
            QSID_FUZZ_REPORT=str(report),
            PYTHONPATH=str(ROOT),
        )
        t0 = time.perf_counter()
        p = subprocess.run(
            [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-k", keyword, *TESTS],
            cwd=ROOT,
            env=env,
            capture_output=True,
            text=True,
        )
        seconds = time.perf_counter() - t0
        counts = json.loads(report.read_text()) if report.exists() else {}
    lines = [x for x in p.stdout.splitlines() if x.strip()]
    return counts, (lines[-1] if lines else p.stderr.strip()[-300:]), seconds


def table(counts: dict) -> str:
    rows = [("entry point", *COLUMNS)]
    for name in sorted(counts):
        rows.append((name, *(str(counts[name].get(c, 0)) for c in COLUMNS)))
    total = {c: sum(v.get(c, 0) for v in counts.values()) for c in COLUMNS}
    rows.append(("all", *(str(total[c]) for c in COLUMNS)))
    width = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(r, width))) for r in rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--examples", type=int, default=2000, help="examples per hypothesis test (default 2000)")
    ap.add_argument("-k", default="fuzz", help="pytest -k expression choosing the tests (default: all fuzz tests)")
    ap.add_argument("--save", help="also write the printed output to this file")
    a = ap.parse_args(argv)
    counts, last, seconds = run(a.examples, a.k)
    bad = {c: sum(v.get(c, 0) for v in counts.values()) for c in BAD}
    out = [
        f"fuzz_engine: {a.examples} randomized examples per test, {len(counts)} entry points, "
        f"{seconds:.0f} s; pytest: {last}",
        table(counts),
        "verdict: " + ("0 other exceptions, 0 hangs, 0 unflagged NaN" if not any(bad.values()) else f"FOUND {bad}"),
        "RESULT " + json.dumps({"benchmark": "fuzz_engine", "examples": a.examples, "counts": counts, "bad": bad}),
    ]
    text = "\n".join(out)
    print(text)
    if a.save:
        Path(a.save).write_text(text + "\n", encoding="utf-8")
    return 0 if not any(bad.values()) and counts else 1


if __name__ == "__main__":
    sys.exit(main())
