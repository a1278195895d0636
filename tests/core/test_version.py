"""The version is written once (qsid_core/version.py) and both programs print it with --version."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from qsid_core.version import __version__

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("module, prog", [("app.cli", "qsid"), ("app.dashboard", "qsid-dashboard")])
def test_both_programs_print_the_one_version(module, prog):
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.run(
        [sys.executable, "-m", module, "--version"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip() == f"{prog} {__version__}"
    assert proc.stderr == ""  # no server started, no kernels compiled


def test_the_version_is_a_release_number():
    parts = __version__.split(".")
    assert len(parts) == 3 and all(p.isdigit() for p in parts)
