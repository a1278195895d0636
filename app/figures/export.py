"""Static figures offline: PNG, SVG and PDF drawn by plotly.js in a local headless Chromium.

No internet: the page is built from a string holding the plotly package's own
``plotly.min.js`` (the full bundle, so 3-D phase portraits draw too; the
dashboard's smaller ``plotly-basic`` has no 3-D traces), and every http(s) request
the page might make is refused. ``Plotly.toImage`` gives PNG and SVG; the PDF is
Chromium's print of the SVG at the figure's size (vector where the figure is).
Chromium is Debian's ``/usr/bin/chromium`` (or ``$QSID_CHROMIUM``), driven by the
``playwright`` package; the browser and the driver end when the call returns.
Without them the figure is written as standalone offline HTML instead, and the
returned note says why.
"""

from __future__ import annotations

import base64
import contextlib
import os
import urllib.parse
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import plotly.graph_objects as go
    from playwright.sync_api import Browser, Page

__all__ = [
    "save_figure",
    "SavedFigure",
    "ExportError",
    "FORMATS",
    "CHROMIUM",
    "chromium_path",
    "figure_format",
    "save_figures",
]

#: File formats by suffix.
FORMATS = ("png", "svg", "pdf", "html")
#: Debian's Chromium (``$QSID_CHROMIUM`` overrides it).
CHROMIUM = "/usr/bin/chromium"
#: Chromium switches: no sandbox (containers), no network services, software rendering.
ARGS = [
    "--no-sandbox",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
    "--disable-gpu",
]
#: Hang guard of every browser step (ms); not a speed target.
TIMEOUT_MS = 120_000

_PAGE = (
    "<!DOCTYPE html><html><head><meta charset='utf-8'><script>{js}</script></head>"
    "<body style='margin:0;background:white'><div id='fig'></div></body></html>"
)
_DRAW = """async ([fig, fmt, w, h, scale]) => {
  const f = JSON.parse(fig);
  const gd = document.getElementById('fig');
  Plotly.purge(gd);
  await Plotly.newPlot(gd, f.data, Object.assign({}, f.layout, {width: w, height: h}), {staticPlot: true});
  return await Plotly.toImage(gd, {format: fmt, width: w, height: h, scale: scale});
}"""


class ExportError(ValueError):
    """A bad path or format for :func:`save_figure` (the message names it)."""


@dataclass(frozen=True)
class SavedFigure:
    """What :func:`save_figure` wrote.

    Attributes
    ----------
    path : pathlib.Path
        The file written (the ``.html`` beside the asked name when it fell back).
    format : str
        ``"png"``, ``"svg"``, ``"pdf"`` or ``"html"``.
    note : str
        "" or one line: why HTML was written instead of the asked format.
    """

    path: Path
    format: str
    note: str = ""


def chromium_path() -> str:
    """The Chromium executable used: ``$QSID_CHROMIUM`` or :data:`CHROMIUM`."""
    return os.environ.get("QSID_CHROMIUM") or CHROMIUM


def figure_format(path: Path) -> str:
    """The format of ``path`` from its suffix (:data:`FORMATS`); :class:`ExportError` for any other or a directory."""
    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in FORMATS:
        raise ExportError(
            f"path: {str(path)!r} has {'the suffix ' + repr(path.suffix) if path.suffix else 'no suffix'}; "
            "give .png, .svg, .pdf or .html"
        )
    if path.is_dir():
        raise ExportError(f"path: {str(path)!r} is a directory; give a file name")
    return fmt


def why_no_browser(browser: str) -> str:
    """Why no static figure can be drawn: "" when Chromium at ``browser`` and playwright are there."""
    if not Path(browser).exists():
        return f"no Chromium at {browser} (apt-get install chromium, or set QSID_CHROMIUM)"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "the playwright package is missing (pip install playwright)"
    return ""


def _size(fig: go.Figure, width: int | None, height: int | None) -> tuple[int, int]:
    w = width or fig.layout.width or 900
    h = height or fig.layout.height or 500
    return int(w), int(h)


@contextmanager
def _chromium(browser: str) -> Iterator[Browser]:
    """A headless Chromium (and its playwright driver), both ended when the block is left."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=browser, headless=True, args=ARGS, timeout=TIMEOUT_MS)
        try:
            yield b
        finally:
            b.close()


def _plotly_page(b: Browser) -> Page:
    """A page of browser ``b`` with plotly.js loaded (from the installed plotly package) and no network."""
    from plotly.offline import get_plotlyjs

    page = b.new_page()
    page.set_default_timeout(TIMEOUT_MS)
    page.route("**/*", lambda route: route.abort() if route.request.url.startswith("http") else route.fallback())
    page.set_content(_PAGE.format(js=get_plotlyjs()))
    return page


def _render(b: Browser, page: Page, fig: go.Figure, fmt: str, w: int, h: int, scale: float) -> bytes:
    """The figure as ``fmt`` bytes, drawn in ``page`` (plotly.js loaded); a PDF is printed in a page of its own."""
    from .raw import to_json

    png = fmt == "png"
    page.set_viewport_size({"width": w, "height": h})
    url = page.evaluate(_DRAW, [to_json(fig), "png" if png else "svg", w, h, scale if png else 1])
    if png:
        return base64.b64decode(url.split(",", 1)[1])
    if fmt == "svg":
        return urllib.parse.unquote(url.split(",", 1)[1]).encode("utf-8")
    pdf = b.new_page(viewport={"width": w, "height": h})
    try:
        pdf.set_default_timeout(TIMEOUT_MS)
        pdf.route("**/*", lambda route: route.abort() if route.request.url.startswith("http") else route.fallback())
        pdf.set_content(
            "<!DOCTYPE html><html><body style='margin:0'>"
            f"<img style='display:block;width:{w}px;height:{h}px' src=\"{url}\"></body></html>"
        )
        pdf.wait_for_function("document.images[0].complete")
        return pdf.pdf(width=f"{w}px", height=f"{h}px", print_background=True, page_ranges="1")
    finally:
        pdf.close()


def _checked(path: str | os.PathLike[str]) -> tuple[Path, str]:
    path = Path(path)
    fmt = figure_format(path)
    if not path.parent.is_dir():
        raise ExportError(f"path: the folder {str(path.parent)!r} does not exist")
    return path, fmt


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _draw(
    static: list[tuple[go.Figure, Path, str]],
    out: dict[Path, SavedFigure],
    width: int | None,
    height: int | None,
    scale: float,
    browser: str,
) -> str:
    """Draw the ``(fig, path, fmt)`` items into ``out``; "" or why Chromium did not start (then nothing is drawn).

    A figure that fails to draw is an :class:`ExportError` with Chromium's first line.
    """
    from playwright.sync_api import Error as PlaywrightError

    with contextlib.ExitStack() as stack:
        try:
            b = stack.enter_context(_chromium(browser))
        except (PlaywrightError, OSError) as exc:
            return f"Chromium at {browser} did not start ({_first_line(exc)})"
        page = _plotly_page(b)  # plotly.js (4.6 MB) parsed once for all figures
        for fig, path, fmt in static:
            w, h = _size(fig, width, height)
            try:
                data = _render(b, page, fig, fmt, w, h, scale)
            except PlaywrightError as exc:
                raise ExportError(f"path: drawing {path.name} in Chromium failed: {_first_line(exc)}") from None
            path.write_bytes(data)
            out[path] = SavedFigure(path, fmt)
    return ""


def save_figures(
    items: Iterable[tuple[go.Figure, str | os.PathLike[str]]],
    width: int | None = None,
    height: int | None = None,
    scale: float = 2.0,
    browser: str | None = None,
) -> list[SavedFigure]:
    """:func:`save_figure` for several ``(fig, path)`` pairs, drawn in one Chromium (started once).

    Returns
    -------
    list of SavedFigure
        In the order of ``items``.
    """
    checked = [(fig, *_checked(path)) for fig, path in items]
    if not scale > 0:
        raise ExportError(f"scale: must be > 0; got {scale!r}")
    browser = browser or chromium_path()
    static = [it for it in checked if it[2] != "html"]
    why = why_no_browser(browser) if static else ""
    out: dict[Path, SavedFigure] = {}
    if static and not why:
        why = _draw(static, out, width, height, scale, browser)
    for fig, path, fmt in checked:
        if path in out:
            continue
        html = path.with_suffix(".html")
        fig.write_html(html, include_plotlyjs=True, full_html=True)
        note = f"{why}: wrote offline HTML {html.name} instead of {path.name}" if fmt != "html" else ""
        out[path] = SavedFigure(html, "html", note)
    return [out[path] for _, path, _ in checked]


def save_figure(
    fig: go.Figure,
    path: str | os.PathLike[str],
    width: int | None = None,
    height: int | None = None,
    scale: float = 2.0,
    browser: str | None = None,
) -> SavedFigure:
    """Write a plotly figure to ``path``; the format comes from the suffix (.png, .svg, .pdf, .html).

    Parameters
    ----------
    fig : plotly.graph_objects.Figure
    path : str or pathlib.Path
        The file to write (replaced if it exists; its folder must exist).
    width, height : int, optional
        Size in CSS pixels (default: the figure's own, else 900 x 500).
    scale : float
        Pixel density of a PNG (2: twice the CSS size).
    browser : str, optional
        Chromium executable (default :func:`chromium_path`).

    Returns
    -------
    SavedFigure
        The file written; for PNG/SVG/PDF without Chromium or playwright, the offline
        ``.html`` beside ``path`` and a one-line ``note`` saying why.

    Raises
    ------
    ExportError
        A suffix that is not one of the four, a directory, a missing folder, or ``scale`` <= 0.
    """
    return save_figures([(fig, path)], width, height, scale, browser)[0]
