"""Sphinx directives that run code while the docs build, so every output shown is real.

``.. qsid-exec::`` runs its Python content (blocks of one page share a namespace, so a later
block can use an earlier block's results) and shows the code and what it printed. With
``:figure: NAME.png`` the namespace's ``fig`` is then written by
:func:`app.figures.save_figure` to ``docs/_generated/NAME.png`` (a local headless Chromium)
and shown; without Chromium the page says why instead.

``.. qsid-cli::`` runs one ``qsid ...`` command line (its content) through
:func:`app.cli.main` and shows the command and its standard output.

An exception or a non-zero exit fails the build (the docs are built with ``-W``).
"""

from __future__ import annotations

import contextlib
import io
import shlex
import textwrap
from pathlib import Path

from docutils import nodes
from docutils.parsers.rst import directives
from sphinx.util.docutils import SphinxDirective

GENERATED = Path(__file__).resolve().parent / "_generated"


def _literal(text: str, language: str) -> nodes.literal_block:
    node = nodes.literal_block(text, text)
    node["language"] = language
    return node


class RunBlock(SphinxDirective):
    has_content = True
    option_spec = {"figure": directives.unchanged, "hide-code": directives.flag}

    def run(self):
        code = textwrap.dedent("\n".join(self.content))
        spaces = self.env.temp_data.setdefault("qsid_run_namespaces", {})
        ns = spaces.setdefault(self.env.docname, {"__name__": "__docs__"})
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            exec(compile(code, f"<{self.env.docname} qsid-exec>", "exec"), ns)
        shown = [] if "hide-code" in self.options else [_literal(code, "python")]
        if out.getvalue().strip():
            shown.append(_literal(out.getvalue().rstrip(), "text"))
        if "figure" in self.options:
            shown += self._figure(ns, self.options["figure"])
        return shown

    def _figure(self, ns: dict, name: str) -> list:
        from app.figures import save_figure

        GENERATED.mkdir(exist_ok=True)
        saved = save_figure(ns["fig"], GENERATED / name)
        if saved.note:  # no Chromium where the docs were built: say so, show no broken image
            return [nodes.paragraph(text=f"(The figure is not shown here: {saved.note}.)")]
        return [nodes.image(uri=f"/_generated/{name}", alt=name, width="100%")]


class CliBlock(SphinxDirective):
    has_content = True

    def run(self):
        from app.cli import main

        line = " ".join(s.strip() for s in self.content if s.strip())
        argv = shlex.split(line)
        if argv[:1] != ["qsid"]:
            raise self.error(f"qsid-cli: the command must start with 'qsid'; got {line!r}")
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(argv[1:])
        if code != 0:
            raise self.error(f"qsid-cli: {line!r} exited with {code}: {err.getvalue().strip()}")
        return [_literal(f"$ {line}\n{out.getvalue().rstrip()}", "console")]


def setup(app):
    app.add_directive("qsid-exec", RunBlock)
    app.add_directive("qsid-cli", CliBlock)
    return {"parallel_read_safe": False, "parallel_write_safe": True}
