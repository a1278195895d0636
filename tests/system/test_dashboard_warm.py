"""The server compiles (or loads) the kernels before it prints its URL, and says so only when it compiles."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

# slow: starts real dashboard processes with an empty kernel cache
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]


def start_and_stop(cache: str) -> list[str]:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=str(ROOT))
    p = subprocess.Popen(
        [sys.executable, "-m", "app.dashboard", "--port", "0", "--workers", "1"],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    lines = []
    try:
        for line in p.stdout:
            lines.append(line.strip())
            if line.startswith("qsid dashboard: http://"):
                break
        p.send_signal(signal.SIGTERM)
        p.wait(60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(10)
    return [x for x in lines if x.startswith("qsid dashboard:")]


def test_compiles_once_before_ready_then_loads_quietly(tmp_path):
    from app.dashboard.warm import kernel_names

    first = start_and_stop(str(tmp_path))
    assert first[0].startswith("qsid dashboard: compiling the kernels once"), first
    assert first[-1].startswith("qsid dashboard: http://")
    cached = {p.name.split("-")[0] for p in tmp_path.rglob("*.nbi")}
    assert cached == set(kernel_names())  # every kernel compiled before the URL
    second = start_and_stop(str(tmp_path))
    assert len(second) == 1 and second[0].startswith("qsid dashboard: http://"), second
