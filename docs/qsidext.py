"""Sphinx directives that generate the docs' outputs and tables when the docs are built.

Nothing shown in the docs is copied by hand: a command's output is produced by running it, and
the dashboard's tables are read from the dashboard's own modules.

``.. qsid-run::``
    Each content line is a shell command run in one fresh temporary directory (so later lines see
    the files earlier ones wrote); ``qsid`` and ``qsid-dashboard`` there are this checkout's
    programs (``python -m app.cli`` / ``python -m app.dashboard``). The block shows ``$ command``
    and what it printed. Options: ``:stderr:`` also show stderr (merged, as a terminal shows it);
    ``:returncode: N`` the exit status every command must have (default 0: a failing command
    fails the build); ``:files: a b`` copy these files from ``docs/data/`` into the directory
    first; ``:hide: N`` run the first N lines without showing them (setup); ``:max-lines: N``
    keep at most N lines of each command's output and say how many were left out.
``.. qsid-python::``
    Runs its content as a Python script in a fresh interpreter (in a temporary directory, the
    checkout on ``PYTHONPATH``) and shows the code, then what it printed.
``.. qsid-controls::``, ``.. qsid-lessons::``, ``.. qsid-views::``
    The dashboard's panel inputs (:data:`app.dashboard.controls.CONTROLS` with the defaults of
    :class:`app.settings.values.Values`), lessons (:data:`app.lessons.table.LESSONS`) and
    plots (:data:`app.figures.registry.VIEWS`) as tables.
``.. qsid-docstring:: MODULE``
    A module's docstring, parsed as reStructuredText (e.g. the dashboard's threading list).
"""

from __future__ import annotations

import importlib
import inspect
import os
import re
import shutil
import stat
import subprocess
import sys
import tempfile
from pathlib import Path

from docutils import nodes
from docutils.parsers.rst import Directive, directives
from docutils.statemachine import StringList
from sphinx.errors import ExtensionError

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).resolve().parent / "data"
TIMEOUT = 900  # a hang guard: the slowest command shown takes seconds


def _env(bin_dir: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env["PATH"] = str(bin_dir) + os.pathsep + env.get("PATH", "")
    env["COLUMNS"] = "200"
    return env


def _programs(bin_dir: Path) -> None:
    """``qsid`` and ``qsid-dashboard`` scripts running this checkout with this interpreter."""
    bin_dir.mkdir()
    for name, module in (("qsid", "app.cli"), ("qsid-dashboard", "app.dashboard"), ("python", None)):
        target = f'exec "{sys.executable}"' + (f" -m {module}" if module else "")
        path = bin_dir / name
        path.write_text(f'#!/bin/sh\n{target} "$@"\n', encoding="utf-8")
        path.chmod(path.stat().st_mode | stat.S_IXUSR)


def _trimmed(text: str, max_lines: int | None) -> str:
    lines = text.rstrip("\n").splitlines()
    if max_lines is None or len(lines) <= max_lines:
        return "\n".join(lines)
    return "\n".join(lines[:max_lines] + [f"... ({len(lines) - max_lines} more lines)"])


def run_commands(commands, *, stderr=False, returncode=0, files=(), hide=0, max_lines=None) -> str:
    """Run shell ``commands`` in one temporary directory; the transcript of the shown ones."""
    shown = []
    with tempfile.TemporaryDirectory(prefix="qsid-docs-") as tmp:
        work, bin_dir = Path(tmp) / "work", Path(tmp) / "bin"
        work.mkdir()
        (work / "examples").symlink_to(ROOT / "examples")  # python examples/NN_name.py works as in the checkout
        _programs(bin_dir)
        for name in files:
            shutil.copy(DATA / name, work / name)
        for i, cmd in enumerate(commands):
            proc = subprocess.run(
                cmd,
                shell=True,
                cwd=work,
                env=_env(bin_dir),
                stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT if stderr else subprocess.PIPE,
                text=True,
                timeout=TIMEOUT,
                start_new_session=True,
            )
            want = 0 if i < hide else returncode
            if proc.returncode != want:
                raise ExtensionError(
                    f"qsid-run: {cmd!r} exited with {proc.returncode}, the docs expect {want}:\n"
                    f"{proc.stdout[-2000:]}{(proc.stderr or '')[-2000:]}"
                )
            if i >= hide:
                out = _trimmed(proc.stdout, max_lines)
                shown.append(f"$ {cmd}" + (f"\n{out}" if out else ""))
    return "\n".join(shown)


class RunDirective(Directive):
    has_content = True
    option_spec = {
        "stderr": directives.flag,
        "returncode": directives.nonnegative_int,
        "files": directives.unchanged,
        "hide": directives.nonnegative_int,
        "max-lines": directives.positive_int,
    }

    def run(self):
        commands = [line for line in self.content if line.strip()]
        text = run_commands(
            commands,
            stderr="stderr" in self.options,
            returncode=self.options.get("returncode", 0),
            files=(self.options.get("files") or "").split(),
            hide=self.options.get("hide", 0),
            max_lines=self.options.get("max-lines"),
        )
        block = nodes.literal_block(text, text)
        block["language"] = "console"
        return [block]


class PythonDirective(Directive):
    has_content = True

    def run(self):
        code = "\n".join(self.content) + "\n"
        with tempfile.TemporaryDirectory(prefix="qsid-docs-") as tmp:
            script = Path(tmp) / "example.py"
            script.write_text(code, encoding="utf-8")
            proc = subprocess.run(
                [sys.executable, str(script)],
                cwd=tmp,
                env=_env(Path(tmp)),
                capture_output=True,
                text=True,
                timeout=TIMEOUT,
            )
        if proc.returncode != 0:
            raise ExtensionError(f"qsid-python: the example failed:\n{proc.stderr[-3000:]}")
        shown = nodes.literal_block(code, code)
        shown["language"] = "python"
        out = proc.stdout.rstrip("\n")
        printed = nodes.literal_block(out, out)
        printed["language"] = "text"
        return [shown, nodes.paragraph(text="prints:"), printed]


def _table(header: list[str], rows: list[list[str]], widths: list[int]) -> nodes.table:
    """A docutils table of plain-text cells (inline literals where a cell is wrapped in backquotes)."""
    table = nodes.table()
    group = nodes.tgroup(cols=len(header))
    table += group
    for w in widths:
        group += nodes.colspec(colwidth=w)

    def row(cells):
        r = nodes.row()
        for c in cells:
            entry = nodes.entry()
            para = nodes.paragraph()
            if c.startswith("``") and c.endswith("``") and len(c) > 4:
                para += nodes.literal(c[2:-2], c[2:-2])
            else:
                para += nodes.Text(c)
            entry += para
            r += entry
        return r

    head = nodes.thead()
    head += row(header)
    body = nodes.tbody()
    for cells in rows:
        body += row(cells)
    group += head
    group += body
    return table


def _range(control) -> str:
    if control.choices:
        return ", ".join(str(c) for c in control.choices)
    if control.kind == "slider":
        return f"{control.lo:g} .. {control.hi:g} (step {control.step:g})"
    if control.kind == "number":
        return f">= {control.lo:g} (step {control.step:g})"
    return {"checkbox": "on / off", "text": "typed"}.get(control.kind, "")


def _default(defaults, control) -> str:
    value = getattr(defaults, control.name, None)
    if value is None or value == "":
        return "(empty)"
    if isinstance(value, bool):
        return "on" if value else "off"
    return str(value)


class ControlsDirective(Directive):
    """One table per panel tab (``""`` = above the tabs), in display order."""

    def run(self):
        from app.dashboard.controls import CONTROLS
        from app.settings.values import Values

        defaults = Values()
        out = []
        tabs = list(dict.fromkeys(c.tab for c in CONTROLS))
        for tab in tabs:
            section = nodes.rubric(text=f"Tab {tab}" if tab else "Above the tabs")
            rows = [
                [
                    c.label + (f" (folder {c.folder})" if c.folder else ""),
                    c.kind,
                    _range(c),
                    _default(defaults, c),
                    (c.hint or "").replace("\n", " "),
                ]
                for c in CONTROLS
                if c.tab == tab
            ]
            out += [
                section,
                _table(["input", "kind", "range / choices", "default", "what it does"], rows, [14, 7, 16, 9, 40]),
            ]
        return out


class LessonsDirective(Directive):
    def run(self):
        from app.lessons.table import LESSONS

        # (the panel's markdown emphasis, e.g. the start text's **fig1**, as plain text)
        rows = [[f"``{les.name}``", les.title, re.sub(r"\*+", "", les.text), les.plot] for les in LESSONS]
        return [_table(["--lesson", "title", "what it says", "key plot"], rows, [10, 14, 60, 8])]


class ViewsDirective(Directive):
    def run(self):
        from app.figures.registry import VIEWS

        rows = []
        for view in VIEWS:
            module = inspect.getmodule(view.build)
            doc = inspect.getdoc(module) or ""
            rows.append([f"``{view.name}``", view.tab, view.depends, doc.split("\n\n")[0].replace("\n", " ")])
        return [_table(["view", "plots tab", "redrawn on", "what it draws"], rows, [10, 10, 7, 50])]


class DocstringDirective(Directive):
    required_arguments = 1

    def run(self):
        module = importlib.import_module(self.arguments[0])
        doc = inspect.getdoc(module) or ""
        container = nodes.container()
        self.state.nested_parse(StringList(doc.splitlines(), source=module.__file__), self.content_offset, container)
        return container.children


def setup(app):
    for name, cls in (
        ("qsid-run", RunDirective),
        ("qsid-python", PythonDirective),
        ("qsid-controls", ControlsDirective),
        ("qsid-lessons", LessonsDirective),
        ("qsid-views", ViewsDirective),
        ("qsid-docstring", DocstringDirective),
    ):
        app.add_directive(name, cls)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}


__all__ = ["run_commands", "setup"]
