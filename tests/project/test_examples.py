"""Every script in examples/ runs (this tree's qsid_core first on the path) and prints what it promises."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

# slow: runs every example script in a fresh interpreter
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = sorted((ROOT / "examples").glob("[0-9][0-9]_*.py"))


def test_there_are_examples_and_the_index_lists_them():
    assert len(SCRIPTS) >= 5
    index = (ROOT / "examples" / "README.md").read_text()
    assert all(p.name in index for p in SCRIPTS)


@pytest.mark.parametrize("script", SCRIPTS, ids=[p.stem for p in SCRIPTS])
def test_example_runs(script, tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    # scripts that write files take a folder as their argument (the others ignore it)
    out = subprocess.run(
        [sys.executable, str(script), str(tmp_path)], cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() and "Traceback" not in out.stderr
    if script.stem == "06_plot_results":  # the PNG (or, without Chromium, its HTML stand-in) and the HTML
        html = (tmp_path / "errors.html").read_text()
        assert "LS, dither tpdf" in html and "Theorem 1 · LS, dither tpdf" in html
        png = tmp_path / "errors.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" if png.exists() else "instead of errors.png" in out.stdout
