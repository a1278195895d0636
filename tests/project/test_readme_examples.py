"""The README's Python examples run and print what the README says they print.

Blocks are found by HTML comments in README.md: ``<!-- readme-example: NAME -->``
before a ```python block, ``<!-- readme-output: NAME -->`` before the block of
its output. Each example runs as a script in a fresh interpreter (cwd a temporary
directory, the repo root on PYTHONPATH). Output is compared line by line: the
text between numbers exactly (whitespace collapsed), the numbers to a tolerance,
so that another BLAS changing the last digits does not fail the test but a
changed result does.
"""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text(encoding="utf-8")
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def block(kind: str, name: str) -> str:
    """The fenced block right after ``<!-- readme-KIND: NAME -->`` (exactly one such marker)."""
    marker = f"<!-- readme-{kind}: {name} -->"
    assert README.count(marker) == 1, f"README.md must contain {marker!r} exactly once"
    m = re.compile(re.escape(marker) + r"\s*```[a-z]*\n(.*?)```", re.S).search(README)
    assert m, f"no fenced block after {marker!r}"
    return m.group(1)


def run_example(name: str, cwd: Path) -> str:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    script = cwd / f"{name}.py"
    script.write_text(block("example", name), encoding="utf-8")
    proc = subprocess.run([sys.executable, str(script)], cwd=cwd, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f"README example {name!r} failed:\n{proc.stderr[-3000:]}"
    return proc.stdout


def assert_same_text(got: str, want: str, rtol: float, atol: float) -> None:
    """Same lines; per line the same words and the same numbers to ``rtol``/``atol``."""
    g_lines, w_lines = got.strip("\n").splitlines(), want.strip("\n").splitlines()
    assert len(g_lines) == len(w_lines), f"{len(g_lines)} lines printed, README shows {len(w_lines)}:\n{got}"
    for g, w in zip(g_lines, w_lines):
        skel_g, skel_w = (" ".join(NUMBER.sub("#", s).split()) for s in (g, w))
        assert skel_g == skel_w, f"line differs from the README:\n  got  {g!r}\n  want {w!r}"
        for a, b in zip(NUMBER.findall(g), NUMBER.findall(w)):
            assert math.isclose(float(a), float(b), rel_tol=rtol, abs_tol=atol), (
                f"number {a} != README's {b} in line\n  got  {g!r}\n  want {w!r}"
            )


def test_number_comparison_catches_a_changed_result():
    assert_same_text("b = 4 err 0.17114", "b =  4 err 0.171141", rtol=1e-4, atol=1e-5)
    with pytest.raises(AssertionError, match="number"):
        assert_same_text("b = 4 err 0.18", "b = 4 err 0.171141", rtol=1e-4, atol=1e-5)
    with pytest.raises(AssertionError, match="line differs"):
        assert_same_text("b = 4 dt 0.1 ['x1']", "b = 4 dt 0.1 ['pos']", rtol=1e-4, atol=1e-5)


@pytest.mark.slow
def test_engine_example_prints_what_the_readme_shows(tmp_path):
    out = run_example("engine", tmp_path)
    assert_same_text(out, block("output", "engine"), rtol=1e-3, atol=1.5e-4)  # printed to 4 decimals


def test_every_output_block_in_the_readme_is_checked():
    """Each ``readme-output`` marker has a test here, and no fenced output block goes without one."""
    names = re.findall(r"<!-- readme-output: ([\w-]+) -->", README)
    assert sorted(names) == ["bits-boeing747", "engine"]
    assert README.count("```console") == len(re.findall(r"<!-- readme-output: [\w-]+ -->\s*```console", README))


@pytest.mark.slow
@pytest.mark.parametrize("system", ["boeing747"])
def test_bits_output_is_what_the_readme_shows(system):
    """The README's ``qsid bits`` tables are this code's output (paper scale)."""
    proc = subprocess.run(
        [sys.executable, "-m", "app.cli", "bits", "--system", system, "-q"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    shown = block("output", f"bits-{system}").split("\n", 1)[1]  # after the '$ qsid bits ...' line
    assert_same_text(proc.stdout, shown, rtol=1e-2, atol=1e-9)
