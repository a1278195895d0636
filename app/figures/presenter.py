"""Presenter style of any figure: text of at least :data:`PLOT_FONT` px and thicker lines, for a lecture hall.

Works on the figure's plain JSON (every font size the views set, the HTML ``font-size:..px`` spans of their
titles, the default font, trace line widths), so every registered view gets it without a change of its own.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import plotly.graph_objects as go

from .axes import log_ticks
from .room import lay_out

__all__ = [
    "PLOT_FONT",
    "NORMAL_FONT",
    "PHONE_FONT",
    "PRESENTER_SIZE",
    "PHONE_WIDTH",
    "LINE_SCALE",
    "presenter_figure",
    "phone_figure",
    "legible_figure",
]

#: Smallest plot text in presenter mode (px).
PLOT_FONT = 18
#: Smallest plot text in normal mode (px): a laptop at arm's length (the legibility test's floor is 10).
NORMAL_FONT = 11
#: Smallest plot text on a phone (px): held closer than a laptop, on a plot a third as wide.
PHONE_FONT = 12
#: The smallest drawing of a plot in presenter mode (px): the plots panel at 1366 × 768 is about 1000 px wide,
#: and the plot 0.6 as high as wide fits under its header (at 1920 × 1080 the same layout is drawn ~1.4 × larger).
PRESENTER_SIZE = (1000.0, 600.0)
#: Presenter mode: a row of panels at least this high (px); a view of many rows (the time series) grows taller
#: than :data:`PRESENTER_SIZE` rather than squeezing them.
MIN_ROW = 55.0
#: The width (px) of a plot on a phone: the plots in the bottom sheet across a 390 px window.
PHONE_WIDTH = 360.0
#: plotly's size of a power label's exponent (10⁻³), relative to the tick font.
SUPERSCRIPT = 0.8
#: Factor on every trace's line width (at least :data:`MIN_LINE` px).
LINE_SCALE, MIN_LINE = 1.8, 3.0
_SPAN = re.compile(r"font-size:\s*(\d+(?:\.\d+)?)px")


def _bigger_text(s: str, floor: float) -> str:
    return _SPAN.sub(lambda m: f"font-size:{max(float(m.group(1)), floor):g}px", s)


def _walk(node: Any, floor: float, in_font: bool = False) -> Any:
    """A copy of ``node`` with every font size raised to ``floor`` and every inline font-size span too."""
    if isinstance(node, dict):
        out = {}
        for k, v in node.items():
            if in_font and k == "size" and isinstance(v, (int, float)):
                out[k] = max(float(v), floor)
            else:
                out[k] = _walk(v, floor, k == "font" or k.endswith("font"))
        return out
    if isinstance(node, list):
        if not any(isinstance(v, (dict, list, str)) for v in node):  # numbers (a trace's data): no font here
            return node
        return [_walk(v, floor) for v in node]
    if isinstance(node, str) and "font-size" in node:
        return _bigger_text(node, floor)
    return node


def _thicker(trace: dict) -> dict:
    """Scatter traces drawn with lines: width x LINE_SCALE (at least MIN_LINE); other traces as they are."""
    if trace.get("type", "scatter") not in ("scatter", "scattergl") or "lines" not in str(trace.get("mode", "lines")):
        return trace
    line = dict(trace.get("line") or {})
    w = line.get("width")
    if isinstance(w, (int, float)) and w == 0:  # an invisible line (a band's edge) stays invisible
        return trace
    line["width"] = max(MIN_LINE, LINE_SCALE * (float(w) if isinstance(w, (int, float)) else 2.0))
    return {**trace, "line": line}


def _plain(fig: go.Figure) -> tuple[list[Any], dict[str, Any]]:
    """The figure's traces and layout as plotly keeps them (plain dicts, read without its deep copy)."""
    data, layout = getattr(fig, "_data", None), getattr(fig, "_layout", None)
    if isinstance(data, list) and isinstance(layout, dict):
        return data, layout
    d = fig.to_plotly_json()
    return list(d.get("data") or []), dict(d.get("layout") or {})


def _without_hover(note: Any) -> Any:
    """A note that keeps its explanation for the hover ("Notes: ... (hover here: why)", the sentences in its
    ``hovertext``) with the sentences as its text (presenter mode and phones)."""
    if not isinstance(note, dict) or not note.get("hovertext") or HOVER_HERE not in str(note.get("text", "")):
        return note
    out = {k: v for k, v in note.items() if k != "hovertext"}
    out["text"] = "Notes: " + str(note["hovertext"])
    return out


def _with_floor(
    fig: go.Figure,
    floor: float,
    thicker: bool,
    inplace: bool = False,
    room: tuple[float, float | None, float] | None = None,
) -> go.Figure:
    data0, layout0 = _plain(fig)
    layout = dict(layout0)
    template = layout.pop("template", None)
    layout = _walk(layout, floor)
    font = dict(layout.get("font") or {})
    font["size"] = max(float(font.get("size") or 0), floor)
    layout["font"] = font
    hover = dict(layout.get("hoverlabel") or {})  # plotly's hover labels are 13 px unless told
    hover["font"] = {
        **(hover.get("font") or {}),
        "size": max(float((hover.get("font") or {}).get("size") or 13), floor),
    }
    layout["hoverlabel"] = hover
    for key, ax in layout.items():
        if (key.startswith("xaxis") or key.startswith("yaxis")) and isinstance(ax, dict) and ax.get("type") == "log":
            tick = dict(ax.get("tickfont") or {})
            # a power label's exponent is drawn at SUPERSCRIPT of the tick font: it too stays at the floor
            tick["size"] = max(float(tick.get("size") or 0), floor / SUPERSCRIPT)
            extra: dict = {}
            if "tickvals" not in ax:  # at most one label per decade: plotly's 2..9 labels crowd at this size
                rng = ax.get("range")
                span = rng[1] - rng[0] if rng else 0.0
                # a tall span on a short plot: every second or third decade (about 8 labels at most)
                extra = log_ticks(rng) if rng and span < 2.5 else {"dtick": max(1, int(np.ceil(span / 8)))}
            layout[key] = {**ax, "tickfont": tick, **extra}
    data = [_walk(t, floor) for t in data0]
    if thicker:
        data = [_thicker(t) for t in data]
    if room is not None:  # drawn at a known size: panels stacked, room measured for every text
        # a projector and a phone have no hover: a note's sentences are shown, not behind "hover here"
        layout["annotations"] = [_without_hover(a) for a in layout.get("annotations") or []]
        lay_out(layout, data, *room)
    if inplace and data0 is getattr(fig, "_data", None) and layout0 is getattr(fig, "_layout", None):
        # plotly's trace and layout objects read these very dicts: replacing their contents restyles the
        # figure without the deep copy of a new one (half of a redraw's figure time otherwise)
        layout0.clear()
        layout0.update(layout)
        if template is not None:
            layout0["template"] = template
        data0[:] = data
        return fig
    out = go.Figure(dict(data=data, layout=layout), _validate=False)
    if template is not None:  # the resolved template (hundreds of entries) is shared, not deep-copied again
        out._layout["template"] = template
    return out


#: How a note says its sentences are behind the hover (:func:`app.figures.error_vs_bits` writes it).
HOVER_HERE = "(hover here: why)"


def presenter_figure(fig: go.Figure, inplace: bool = False) -> go.Figure:
    """``fig`` in presenter style: text of at least :data:`PLOT_FONT` px, thicker lines, laid out for
    :data:`PRESENTER_SIZE` (:func:`app.figures.room.lay_out`) (a new figure, or ``fig`` itself restyled with
    ``inplace``)."""
    return _with_floor(fig, PLOT_FONT, thicker=True, inplace=inplace, room=(*PRESENTER_SIZE, MIN_ROW))


def phone_figure(fig: go.Figure, inplace: bool = False) -> go.Figure:
    """``fig`` for a phone: text of at least :data:`PHONE_FONT` px, laid out :data:`PHONE_WIDTH` px wide and as
    high as its panels need, stacked (``layout.height`` says how high)."""
    return _with_floor(fig, PHONE_FONT, thicker=False, inplace=inplace, room=(PHONE_WIDTH, None, 0.0))


def legible_figure(fig: go.Figure, inplace: bool = False) -> go.Figure:
    """``fig`` with no text under :data:`NORMAL_FONT` px (a new figure and ``fig`` left as it is, or ``fig``
    itself restyled with ``inplace``)."""
    return _with_floor(fig, NORMAL_FONT, thicker=False, inplace=inplace)
