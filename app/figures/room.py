"""Room for every text of a figure drawn at a known size: panels stacked, text blocks measured, nothing cut off.

Presenter mode (text of at least 18 px, for a projector) and a phone (a plot about 360 px wide) draw the same
views as a laptop does. :func:`lay_out` rearranges a figure's plain layout (the dicts plotly keeps) for a drawing
``width`` px wide and ``height`` px high (or as high as it needs):

* panels side by side (one row of subplots, as the error plot's Â and B̂, or a grid of such rows) are stacked,
  each as wide as the figure, column by column, each keeping its share of the height; the title standing on a
  panel's top edge goes with it;
* the figure's title and the notes above the plot become one block of text at the top, wrapped to the width,
  and the top margin is that block's height (plotly does not grow a margin for a title of several lines);
* between stacked rows there is room for the upper row's tick labels and axis title and the lower row's title;
* a y-axis title longer than its row is high is broken into lines, and a low row gets fewer y ticks;
* the legend stands at the figure's foot, the bottom margin holding all of its rows.

Text sizes are estimated from character counts (:data:`CHAR` of the font size per character, :data:`LINE` per
line), on the generous side; ``tests/system/test_dashboard_legibility.py`` measures the result in a browser.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

__all__ = ["lay_out", "wrap_text", "text_width", "CHAR", "LINE"]

#: Width of an average character, in font sizes (measured ~0.42 for prose in Chromium's sans-serif; digits
#: and capitals are wider).
CHAR = 0.52
#: Height of a line of text, in font sizes (plotly's line spacing).
LINE = 1.35
#: Space (px) kept between two blocks of text.
PAD = 8.0
#: Gap between an x axis and its tick labels, in font sizes (clear of a y tick label at the same corner).
STANDOFF = 0.6
_TAG = re.compile(r"<[^>]*>")
_BR = re.compile(r"<br\s*/?>", re.I)


def _plain(text: str) -> str:
    return _TAG.sub("", text)


def text_width(text: str, size: float) -> float:
    """Estimated width (px) of the widest line of ``text`` (HTML tags not counted) at ``size`` px."""
    return max((len(_plain(line)) for line in _BR.split(text)), default=0) * CHAR * size


def _lines(text: str) -> int:
    return len(_BR.split(text)) if text else 0


def _sentences(text: str) -> list[str]:
    """The lines of ``text``, a line joined to the one before when it only continues its sentence (the one before
    ends in a letter, digit or comma and it starts in lower case): breaks a view made for a laptop's width."""
    out: list[str] = []
    for line in _BR.split(text):
        prev = _plain(out[-1]).rstrip() if out else ""
        if prev and (prev[-1].isalnum() or prev[-1] == ",") and _plain(line)[:1].islower():
            out[-1] = f"{out[-1].rstrip()} {line.lstrip()}"
        else:
            out.append(line)
    return out


def wrap_text(text: str, chars: int) -> str:
    """``text`` with each of its lines broken (``<br>``) at spaces into lines of at most ``chars`` characters
    (HTML tags not counted; a break never falls inside a tag; a sentence broken for another width is joined
    first)."""
    out: list[str] = []
    for line in _sentences(text):
        words = re.split(r" (?![^<]*>)", line)  # spaces outside tags
        cur, n = "", 0
        for w in words:
            k = len(_plain(w))
            if cur and n + 1 + k > chars:
                out.append(cur)
                cur, n = w, k
            else:
                cur, n = (f"{cur} {w}", n + 1 + k) if cur else (w, k)
        out.append(cur)
    return "<br>".join(out)


def _key(ref: str, letter: str) -> str:
    """An axis reference ('y', 'y2', 'y3 domain') -> its layout key ('yaxis', 'yaxis2', 'yaxis3')."""
    ref = (ref or letter).split(" ")[0]
    return f"{letter}axis{ref[1:]}"


def _size(node: Any, default: float) -> float:
    font = node.get("font") if isinstance(node, dict) else None
    s = font.get("size") if isinstance(font, dict) else None
    return float(s) if isinstance(s, (int, float)) else default


def _axes(layout: dict, letter: str) -> dict[str, dict]:
    return {k: v for k, v in layout.items() if re.fullmatch(f"{letter}axis\\d*", k) and isinstance(v, dict)}


def _on_paper(ann: dict) -> bool:
    return ann.get("xref", "paper") == "paper" and ann.get("yref", "paper") == "paper"


def _stack(layout: dict) -> bool:
    """Panels side by side (a row of x domains apart, or a grid of such rows) -> one above the other, each full
    width: column by column from the left, each column top to bottom, each panel keeping its share of the height
    (a column's title stays over its top panel); True if done."""
    rows: dict[tuple, list[tuple[float, float, str, str]]] = {}
    for xk, ax in _axes(layout, "x").items():
        yk = _key(str(ax.get("anchor") or "y"), "y")
        dom = list(ax.get("domain") or [0.0, 1.0])
        ydom = tuple(float(v) for v in (layout.get(yk) or {}).get("domain") or (0, 1))
        rows.setdefault(ydom, []).append((float(dom[0]), float(dom[1]), xk, yk))
    if sum(map(len, rows.values())) < 2 or all(len(r) < 2 for r in rows.values()):
        return False  # one panel, or a column of them already
    for r in rows.values():
        r.sort()
        if any(b[0] < a[1] - 1e-6 for a, b in zip(r, r[1:])):
            return False  # overlapping x domains: not side by side
    top_row = max(rows, key=lambda d: d[1])
    panels = sorted(((p, d) for d, r in rows.items() for p in r), key=lambda pd: (pd[0][0], -pd[1][1]))
    total = sum(d[1] - d[0] for _, d in panels) or 1.0
    anns = [a for a in layout.get("annotations") or [] if _on_paper(a) and a.get("xanchor") == "center"]
    heads = [(a, float(a.get("y", 0)), float(a.get("x", 0))) for a in anns]
    top = 1.0
    for (x0, x1, xk, yk), d in panels:
        low = max(0.0, top - (d[1] - d[0]) / total)
        layout[xk] = {**layout[xk], "domain": [0.0, 1.0]}
        layout[yk] = {**(layout.get(yk) or {}), "domain": [low, top]}
        for a, y, x in heads:  # a panel's title (centred on its top edge) goes with the panel
            on_top = y >= 0.999 if d == top_row else abs(y - d[1]) < 0.02
            if on_top and x0 - 1e-6 <= x <= x1 + 1e-6:
                a.update(x=0.5, y=top)
        top = low
    return True


@dataclass
class _Row:
    ys: list[str]
    lo: float
    hi: float
    x: str | None = None
    heads: list[dict] = field(default_factory=list)
    px: float = 0.0


def _rows(layout: dict) -> list[_Row]:
    """The rows of panels, top first; each with the x axis drawn under it (if any)."""
    rows: dict[tuple[float, float], _Row] = {}
    for yk, ax in _axes(layout, "y").items():
        if ax.get("overlaying"):
            continue
        lo, hi = (float(v) for v in (ax.get("domain") or (0.0, 1.0)))
        rows.setdefault((round(lo, 4), round(hi, 4)), _Row([], lo, hi)).ys.append(yk)
    if not rows:
        rows[(0.0, 1.0)] = _Row(["yaxis"], 0.0, 1.0)
    out = sorted(rows.values(), key=lambda r: -r.hi)
    for xk, ax in (_axes(layout, "x") or {"xaxis": {}}).items():
        yk = _key(str(ax.get("anchor") or "y"), "y")
        for r in out:
            if yk in r.ys and ax.get("visible", True) is not False:
                r.x = xk
    return out


def _tick_h(ax: dict, size: float, standoff: bool = True) -> float:
    """Height (px) of the tick labels of ``ax`` (with an x axis's gap above them, :data:`STANDOFF`)."""
    if ax.get("visible", True) is False or ax.get("showticklabels", True) is False:
        return 0.0
    s = _size({"font": ax.get("tickfont") or {}}, size)
    power = ax.get("type") == "log" and ax.get("exponentformat") == "power"
    return LINE * s * (1.25 if power else 1.0) + (STANDOFF * s if standoff else 0.0)


def _title_h(ax: dict, size: float, chars: int | None = None) -> float:
    title = ax.get("title") or {}
    text = str(title.get("text") or "") if isinstance(title, dict) else str(title)
    if not text or ax.get("visible", True) is False:
        return 0.0
    if chars is not None and isinstance(title, dict):
        title["text"] = text = wrap_text(text, chars)
    return LINE * _size(title, size) * _lines(text) + 4


def _y_ticks_h(layout: dict, row: _Row, size: float) -> float:
    """Room (px) between two rows sharing an x axis: half a tick label of each meets there."""
    return max((_tick_h(layout.get(yk) or {}, size, standoff=False) for yk in row.ys), default=0.0) + 2.0


def _block(anns: list[dict], size: float) -> float:
    """Height (px) of annotations stacked on one edge (their tallest)."""
    return max((LINE * _size(a, size) * _lines(str(a.get("text", ""))) + 4 for a in anns), default=0.0)


def _legend_h(layout: dict, data: list, width: float, size: float) -> float:
    """Height (px) of a horizontal legend across ``width``, placed at the figure's foot."""
    if layout.get("showlegend") is False:
        return 0.0
    shown = [str(t.get("name") or "") for t in data if t.get("showlegend", True) is not False and t.get("name")]
    if len(shown) < 2 and layout.get("showlegend") is not True:
        return 0.0
    leg = layout.get("legend") or {}
    s = _size(leg, size)
    rows, x = 1, 0.0
    for name in shown:
        w = 46 + CHAR * s * len(_plain(name))
        if x and x + w > width - 10:
            rows, x = rows + 1, 0.0
        x += w
    layout["legend"] = {**leg, "orientation": "h", "x": 0, "xanchor": "left", "yref": "container", "y": 0}
    layout["legend"]["yanchor"] = "bottom"
    return rows * (LINE * s + 5) + PAD


def _title_block(layout: dict, width: float, size: float) -> dict | None:
    """The figure's title as an annotation (top left, wrapped to ``width``), or None without a title."""
    title = layout.get("title")
    text = str(title.get("text") or "") if isinstance(title, dict) else str(title or "")
    if not text:
        return None
    font = {**(layout.get("font") or {}), **((title.get("font") if isinstance(title, dict) else None) or {})}
    s = _size({"font": font}, size)
    layout["title"] = {"text": ""}
    chars = max(12, int((width - 12) / (CHAR * s)))
    color = {"color": font["color"]} if "color" in font else {}
    place = dict(xref="paper", x=0, xanchor="left", yref="paper", y=1, yanchor="bottom")
    return dict(text=wrap_text(text, chars), showarrow=False, align="left", font={"size": s, **color}, **place)


def _thin_ticks(ax: dict, room: float, per_label: float) -> None:
    """At most ``room / per_label`` tick labels on ``ax`` (an explicit list keeps its powers of ten first)."""
    most = max(2, int(room // per_label))
    vals = ax.get("tickvals")
    if isinstance(vals, list) and len(vals) > most:
        text = ax.get("ticktext") or [str(v) for v in vals]
        keep = [i for i, t in enumerate(text) if "×" not in str(t) and str(t).lstrip("0.").startswith("1")]
        if len(keep) > most or len(keep) < 2:
            keep = list(range(0, len(vals), -(-len(vals) // most)))
        ax["tickvals"], ax["ticktext"] = [vals[i] for i in keep], [text[i] for i in keep]
    elif ax.get("type") == "log" and isinstance(ax.get("dtick"), (int, float)) and ax.get("range"):
        span = float(ax["range"][1]) - float(ax["range"][0])  # decades
        ax["dtick"] = max(float(ax["dtick"]), float(-(-span // most)))
    elif not isinstance(vals, list) and "dtick" not in ax:
        ax["nticks"] = most


def lay_out(
    layout: dict, data: list, width: float, height: float | None = None, min_row: float = 0.0, stack: bool = True
) -> float:
    """Rearrange ``layout`` (in place) for a drawing ``width`` px wide; returns its height (px), also written to
    ``layout["height"]``.

    The height is ``height``, grown until every row of panels is at least ``min_row`` px high; without
    ``height``, rows of 0.6 × ``width`` (0.42 × ``width`` each when there are several). The rules are in the
    module docstring.
    """
    size = _size(layout, 12.0)
    if stack:
        _stack(layout)
    rows = _rows(layout)
    anns = [a for a in layout.get("annotations") or [] if isinstance(a, dict)]
    top_notes: list[dict] = []
    for a in anns:
        if not _on_paper(a) or a.get("yanchor") != "bottom":
            continue
        y = float(a.get("y", 0))
        for i, r in enumerate(rows):
            if abs(y - r.hi) < 0.02 or (i == 0 and y >= 0.999):
                (r.heads if i > 0 or a.get("xanchor") == "center" else top_notes).append(a)
                break
    chars = max(12, int((width - 20) / (CHAR * size)))
    left = float((layout.get("margin") or {}).get("l", 80))
    for a in top_notes + [h for r in rows for h in r.heads]:
        if a in top_notes and float(a.get("x", 0)) == 0 and a.get("xanchor") == "left":
            a["xshift"] = 6 - left  # from the figure's left edge, as wide as the figure
        a["text"] = wrap_text(str(a.get("text", "")), chars)
    title = _title_block(layout, width, size)
    if title is not None:
        title["xshift"] = 6 - left
    # clear of text standing on the plot's top edge, and of the top y tick label (half of it stands above)
    shift = _block(rows[0].heads, size) + max(PAD / 2, 0.6 * _y_ticks_h(layout, rows[0], size))
    for a in sorted(top_notes, key=lambda a: float(a.get("yshift") or 0)):
        a["yshift"] = shift
        shift += _block([a], size)
    if title is not None:
        title["yshift"] = shift
        layout["annotations"] = [*anns, title]
    top = shift + (_block([title], size) if title else 0.0) + PAD
    xs = _axes(layout, "x")
    # under a row: its x axis (tick labels, title), or room for the tick labels of two y axes meeting there
    under = [
        (_tick_h(xs[r.x], size) + _title_h(xs[r.x], size, chars) + PAD) if r.x in xs else _y_ticks_h(layout, r, size)
        for r in rows
    ]
    heads = [_block(r.heads, size) for r in rows]
    gaps = [0.0] + [under[i - 1] + heads[i] + (PAD if heads[i] else PAD / 2) for i in range(1, len(rows))]
    bottom = under[-1] + _legend_h(layout, data, width, size)
    fixed = top + bottom + sum(gaps)
    # notes standing above the plot (shown in full where there is no hover) add to the height asked for: the
    # panels keep the room they would have without them
    each = (
        (height + sum(_block([a], size) for a in top_notes) - fixed) / len(rows)
        if height is not None
        else (0.6 if len(rows) == 1 else 0.42) * width
    )
    height = fixed + max(each, min_row, 40.0) * len(rows)
    layout["height"] = round(height)
    total = sum(r.hi - r.lo for r in rows) or 1.0
    avail = height - fixed
    paper, cursor = height - top - bottom, 0.0
    for r, gap in zip(rows, gaps):
        r.px = avail * (r.hi - r.lo) / total
        cursor += gap
        hi = 1.0 - cursor / paper
        cursor += r.px
        lo = 1.0 - cursor / paper
        for yk in r.ys:
            layout[yk] = {**(layout.get(yk) or {}), "domain": [max(0.0, round(lo, 4)), min(1.0, round(hi, 4))]}
        for a in r.heads:
            a["y"] = min(1.0, round(hi, 4))
    _fit_axes(layout, rows, width, size)
    margin = dict(layout.get("margin") or {})
    margin.update(t=round(top), b=round(bottom))
    layout["margin"] = margin
    return float(height)


def _fit_axes(layout: dict, rows: list[_Row], width: float, size: float) -> None:
    """Y titles broken to their row's height, fewer y ticks on low rows, fewer x labels on narrow plots."""
    for r in rows:
        for yk in r.ys:
            ax = layout[yk]
            s = _size({"font": ax.get("tickfont") or {}}, size)
            _thin_ticks(ax, r.px, 2.0 * s)
            title = ax.get("title")
            if isinstance(title, dict) and title.get("text"):
                ts = _size(title, size)
                if text_width(str(title["text"]), ts) > r.px:
                    title["text"] = wrap_text(str(title["text"]), max(4, int(r.px / (CHAR * ts))))
    margin = layout.get("margin") or {}
    plot_w = width - float(margin.get("l", 80)) - float(margin.get("r", 80))
    for ax in _axes(layout, "x").values():
        s = _size({"font": ax.get("tickfont") or {}}, size)
        labels = ax.get("ticktext") or []
        longest = max((len(_plain(str(t))) for t in labels), default=5)
        _thin_ticks(ax, plot_w, CHAR * s * longest + 2.5 * s)
        ax["ticklabelstandoff"] = round(STANDOFF * s)  # clear of the y labels at the plot's lower corners
