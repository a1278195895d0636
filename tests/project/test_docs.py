"""The docs stay true: every module is placed in the architecture page, the README stays short, and
the build-time output directive fails on a command that fails."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"


#: each package's modules are placed in its own section of docs/architecture.rst
SECTIONS = {
    "qsid_core": "The engine, ``qsid_core/``",
    "qsid_core/plant": "The engine, ``qsid_core/``",
    "qsid_core/quantization": "The engine, ``qsid_core/``",
    "qsid_core/identification": "The engine, ``qsid_core/``",
    "qsid_core/control": "The engine, ``qsid_core/``",
    "qsid_core/studies": "The engine, ``qsid_core/``",
    "app": "The command line, ``app/cli/``",  # app/distributed.py and app/procs.py sit beside the CLI
    "app/cli": "The command line, ``app/cli/``",
    "app/settings": "Settings, ``app/settings/``",
    "app/frames": "What a front end shows, ``app/frames/``",
    "app/lessons": "Lessons, ``app/lessons/``",
    "app/dashboard": "The dashboard, ``app/dashboard/``",
    "app/figures": "The views, ``app/figures/``",
}


def _section(page: str, title: str) -> str:
    start = page.index(title + "\n")
    later = [page.index(t + "\n") for t in SECTIONS.values() if page.index(t + "\n") > start]
    return page[start : min(later, default=len(page))]


@pytest.mark.parametrize("package", sorted(SECTIONS))
def test_the_architecture_page_names_every_module(package):
    page = (DOCS / "architecture.rst").read_text(encoding="utf-8")
    section = _section(page, SECTIONS[package])
    modules = sorted((ROOT / package).glob("*.py"))
    assert len(modules) >= 2
    missing = [str(p.relative_to(ROOT)) for p in modules if f"{p.name}``" not in section]
    assert not missing, f"docs/architecture.rst does not say where these live: {missing}"


def test_every_line_count_a_page_cites_is_the_files_length_now():
    """A page saying ``path/to/module.py`` (N lines) is right about it (``wc -l``): the counts went stale before."""
    pattern = re.compile(r"``([\w/]+\.py)`` \((\d+) lines\)")
    cited = [m.groups() for page in sorted(DOCS.glob("*.rst")) for m in pattern.finditer(page.read_text("utf-8"))]
    assert len(cited) >= 3
    lengths = {path: (int(n), (ROOT / path).read_text("utf-8").count("\n")) for path, n in cited}
    wrong = {path: f"said {said}, is {now}" for path, (said, now) in lengths.items() if said != now}
    assert not wrong, wrong


def test_readme_is_at_most_250_lines():
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 250, f"README.md has {len(lines)} lines"


def test_readme_keeps_the_ci_test_command_and_the_quick_subset():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert "python -m pytest\n" in ci and "python -m pytest " in readme
    assert 'python -m pytest -m "not slow"' in readme


def test_every_page_in_the_toctree_exists_and_every_page_is_in_it():
    index = (DOCS / "index.rst").read_text(encoding="utf-8")
    listed = {line.strip() for line in index.splitlines() if line.startswith("   ") and ":" not in line}
    listed.discard("")
    pages = {p.stem for p in DOCS.glob("*.rst")} - {"index"}
    assert listed == pages


def test_qsid_run_fails_the_build_on_an_unexpected_exit_status():
    pytest.importorskip("sphinx")
    sys.path.insert(0, str(DOCS))
    try:
        from qsidext import run_commands
        from sphinx.errors import ExtensionError
    finally:
        sys.path.remove(str(DOCS))
    assert run_commands(["echo hello"]) == "$ echo hello\nhello"
    assert run_commands(["printf 'a\\nb\\nc\\n'"], max_lines=2) == "$ printf 'a\\nb\\nc\\n'\na\nb\n... (1 more lines)"
    with pytest.raises(ExtensionError, match="exited with 3"):
        run_commands(["exit 3"])
    assert run_commands(["echo oops >&2; exit 2"], stderr=True, returncode=2) == "$ echo oops >&2; exit 2\noops"


def test_qsid_in_a_docs_command_is_this_checkout():
    pytest.importorskip("sphinx")
    sys.path.insert(0, str(DOCS))
    try:
        from qsidext import run_commands
    finally:
        sys.path.remove(str(DOCS))
    from qsid_core.version import __version__

    assert run_commands(["qsid --version"]) == f"$ qsid --version\nqsid {__version__}"


#: the pages of this docs set whose shown outputs all come from qsid-run / qsid-python
GENERATED_PAGES = ["index", "getting-started", "dashboard", "cli-guide", "science", "examples", "architecture"]


@pytest.mark.parametrize("page", GENERATED_PAGES)
def test_hand_written_console_blocks_hold_commands_only(page):
    """Output in a page comes from running the command at build time, never typed into a console block."""
    text = (DOCS / f"{page}.rst").read_text(encoding="utf-8")
    blocks = re.findall(r"^\.\. code-block:: console\n\n((?:   .*\n|\n)+)", text, re.M)
    for block in blocks:
        lines = [line.strip() for line in block.splitlines() if line.strip()]
        assert all(line.startswith("$ ") for line in lines), f"{page}.rst shows output by hand:\n{block}"
