"""The ``--figure FILE`` / ``--figure-view`` options: a sweep's figure as PNG, SVG, PDF or offline HTML.

The figure is :func:`app.figures.results.plot_results` of the run's result, written by
:func:`app.figures.export.save_figure` (a local headless Chromium; without it, offline
HTML beside the asked name and a note on stderr saying why).
"""

from __future__ import annotations

import argparse
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from .files import out_file
from .runner import Reporter, UsageError

if TYPE_CHECKING:
    import plotly.graph_objects as go

    from qsid_core import SweepResult

#: The views ``--figure-view`` offers: those of :func:`app.figures.results.plot_results` (a test checks they agree),
#: written out so that building the parser does not import plotly.
FIGURE_VIEWS = ("error", "cost", "stabilized", "bound")

__all__ = [
    "FIGURE_VIEWS",
    "add_figure_arguments",
    "check_figure",
    "write_figure",
    "check_formats",
    "save",
    "save_panels",
    "index_page",
]

_INDEX = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>{title}</title>
<script src="plotly.min.js"></script>
<style>
body {{ font-family: system-ui, sans-serif; margin: 1em 2em; color: #222; }}
.grid {{ display: grid; grid-template-columns: repeat(3, minmax(0, 1fr)); gap: 1em; }}
.panel {{ border: 1px solid #ddd; border-radius: 4px; padding: 0.3em; min-width: 0; }}
.panel h2 {{ font-size: 1em; margin: 0.2em 0.4em; }}
@media (max-width: 1100px) {{ .grid {{ grid-template-columns: 1fr; }} }}
</style></head>
<body>
<h1>{title}</h1>
<p>{caption}</p>
<p>Data: <a href="data.json">data.json</a>. Panels as separate pages: {links}.</p>
<div class="grid">
{panels}
</div>
</body></html>
"""


def add_figure_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("figure")
    g.add_argument(
        "--figure",
        metavar="FILE",
        default=None,
        help="also draw the result to FILE: .png, .svg or .pdf (drawn offline by a local headless Chromium, "
        "/usr/bin/chromium or $QSID_CHROMIUM; without it offline .html beside FILE, with a note why) or .html",
    )
    g.add_argument(
        "--figure-view",
        choices=FIGURE_VIEWS,
        default="error",
        help="what --figure draws: relative errors of A and B with Theorem 1 (error), the closed-loop MPC "
        "cost (cost), the share of loops that converge and the cost gap (stabilized) or the ultimate bound "
        "(bound) against b (default: error)",
    )


def check_figure(
    args: argparse.Namespace,
    rep: Reporter,
    inputs: Sequence[str | Path] = (),
    others: Iterable[tuple[str, Path | None]] = (),
) -> Path | None:
    """Check ``--figure`` before the run: a known suffix, a writable place, not an input or another output."""
    if args.figure is None:
        return None
    from app.figures.export import ExportError, figure_format

    path = out_file(args.figure, rep, flag="--figure", inputs=inputs)
    if path is None:
        raise UsageError("argument --figure: give a file name")
    try:
        figure_format(path)
    except ExportError as exc:
        raise UsageError(f"argument --figure: {str(exc).removeprefix('path: ')}") from None
    for flag, other in others:
        if other is not None and other.resolve() == path.resolve():
            raise UsageError(f"arguments {flag} and --figure name the same file; give two names")
    if getattr(args, "no_mpc", False) and args.figure_view in ("cost", "stabilized"):
        raise UsageError(f"argument --figure-view: {args.figure_view!r} needs the closed loops; drop --no-mpc")
    return path


def save(fig: go.Figure, path: Path, rep: Reporter) -> Path:
    """Write ``fig`` to ``path``; a fallback to HTML is said on stderr. Returns the file written."""
    from app.figures.export import save_figure

    saved = save_figure(fig, path)
    if saved.note:
        rep.line(f"note: --figure: {saved.note}")
    return saved.path


def save_panels(items: Iterable[tuple[go.Figure, Path]], rep: Reporter) -> list[Path]:
    """Write ``(fig, path)`` pairs in one Chromium; without it nothing (the HTML is there) and a note why."""
    from app.figures.export import chromium_path, save_figures, why_no_browser

    why = why_no_browser(chromium_path())
    if why:
        rep.line(f"note: --figure: {why}: only the HTML panels were written")
        return []
    return [s.path for s in save_figures(items)]


def write_figure(result: SweepResult, path: Path | None, view: str, rep: Reporter) -> None:
    """Draw ``result`` (a SweepResult) as ``view`` into ``path`` (nothing when ``path`` is None)."""
    if path is None:
        return
    from app.figures.presenter import legible_figure
    from app.figures.results import plot_results

    # the dashboard's laptop style: no text under 11 px, one labelled tick per decade on log axes
    written = save(legible_figure(plot_results(result, view=view)), path, rep)
    rep.stage(f"figure ({view}) written to {written}")


def check_formats(text: str | None) -> tuple[str, ...]:
    """``--figure png,svg`` of ``qsid reproduce``: the static formats asked for (empty when None)."""
    if text is None:
        return ()
    fmts = tuple(dict.fromkeys(f.strip().lower().lstrip(".") for f in text.split(",") if f.strip()))
    bad = [f for f in fmts if f not in ("png", "svg", "pdf")]
    if not fmts or bad:
        raise UsageError(
            f"argument --figure: give png, svg and/or pdf, comma-separated (the HTML is always written); got {text!r}"
        )
    return fmts


def index_page(title: str, caption_html: str, panels: Sequence[tuple[str, go.Figure]]) -> str:
    """``index.html`` of a ``reproduce`` folder: every panel drawn inline (the folder's ``plotly.min.js``), under a
    heading that links to the panel's own page ``<stem>.html``; ``caption_html`` is already escaped."""
    import html

    import plotly.graph_objects as go
    import plotly.io as pio

    divs = []
    for stem, fig in panels:
        heading = fig.layout.title.text or stem
        fig = go.Figure(fig)  # a copy without the title: the page heading carries it
        fig.update_layout(title=None, margin=dict(t=30))
        div = pio.to_html(
            fig, include_plotlyjs=False, full_html=False, div_id=f"panel-{stem}", config={"responsive": True}
        )
        divs.append(f'<div class="panel"><h2><a href="{stem}.html">{html.escape(heading)}</a></h2>\n{div}\n</div>')
    return _INDEX.format(
        title=html.escape(title),
        caption=caption_html,
        links=", ".join(f'<a href="{s}.html">{s}</a>' for s, _ in panels),
        panels="\n".join(divs),
    )
