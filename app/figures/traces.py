"""Helpers shared by the plot builders: reading rows, mean +- std bands, the current-b marker.

Inputs are plain data: *rows* are the JSON-ready per-b summaries of
:func:`qsid_core.studies.summary.summary_row` (the ``results`` entries of
``qsid sweep --json``); a *series* maps a label (``"LS"``, ``"BCLS"``) to a list
of rows. Missing values (``None``) are skipped, so partially filled sweeps draw.
The only arithmetic here is reshaping for display.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import plotly.graph_objects as go

from .palette import COLORS
from .raw import to_json

__all__ = [
    "Rows",
    "Series",
    "get",
    "xy",
    "band",
    "mark_bits",
    "hline_note",
    "move_current_bits",
    "with_current_bits",
    "has_current_bits",
    "MarkedAt",
    "BITS_AXIS",
]

Rows = Sequence[Mapping[str, Any]]
Series = Mapping[str, Rows]
#: x axis of every plot against the word length.
BITS_AXIS: dict[str, Any] = dict(title=dict(text="word length b [bits]"), dtick=2)
#: name of the current-b marker shapes (the only vertical lines a b change moves)
CURRENT_B = "current b"


def get(row: Mapping[str, Any], *path: str) -> Any:
    """``row[path[0]][path[1]]...``, None where a level is missing."""
    v: Any = row
    for p in path:
        if v is None:
            return None
        v = v.get(p) if isinstance(v, Mapping) else None
    return v


def xy(rows: Rows, *path: str) -> tuple[list[int], list[float]]:
    """(b, value) of every row whose value at ``path`` is finite and positive (log axes), sorted by b."""
    xs: list[int] = []
    ys: list[float] = []
    for r in sorted(rows, key=lambda r: r["bits"]):
        v = get(r, *path)
        if v is not None and np.isfinite(v) and v > 0:
            xs.append(r["bits"])
            ys.append(float(v))
    return xs, ys


def band(
    rows: Rows, key: str, color: str, name: str, xaxis: str = "x", yaxis: str = "y", showlegend: bool = True
) -> list:
    """Trace dicts: mean line with a mean +- std band (clipped above zero for the log axis); [] if no mean."""
    pts = []
    for r in sorted(rows, key=lambda r: r["bits"]):
        m, s = get(r, key, "mean"), get(r, key, "std")
        if m is not None and np.isfinite(m) and m > 0:
            pts.append((r["bits"], m, s if s is not None and np.isfinite(s) else 0.0))
    if not pts:
        return []
    b = [p[0] for p in pts]
    m = np.array([p[1] for p in pts], dtype=float)
    s = np.array([p[2] for p in pts], dtype=float)
    lo = np.where(m - s > 0, m - s, m / 10)
    ax = dict(xaxis=xaxis, yaxis=yaxis)
    return [
        dict(
            type="scatter",
            x=b + b[::-1],
            y=(m + s).tolist() + lo[::-1].tolist(),
            mode="lines",
            fill="toself",
            fillcolor=color,
            opacity=0.18,
            line=dict(width=0),
            hoverinfo="skip",
            showlegend=False,
            legendgroup=name,
            **ax,
        ),
        dict(
            type="scatter",
            x=b,
            y=m.tolist(),
            mode="lines+markers",
            name=name,
            legendgroup=name,
            showlegend=showlegend,
            line=dict(color=color),
            error_y=dict(type="data", array=s.tolist(), visible=False),
            **ax,
        ),
    ]


def mark_bits(current_bits: int | None, axes: Sequence[tuple[str, str]] = (("x", "y"),)) -> list[dict[str, Any]]:
    """Shape dicts: a dotted vertical line at the current word length on each (x, y) axis pair ([] if None)."""
    if current_bits is None:
        return []
    return [
        dict(
            type="line",
            x0=current_bits,
            x1=current_bits,
            xref=xa,
            y0=0,
            y1=1,
            yref=f"{ya} domain",
            line=dict(color=COLORS["marker"], dash="dot", width=1),
            name=CURRENT_B,
        )
        for xa, ya in axes
    ]


def hline_note(
    y: float,
    text: str,
    yaxis: str = "y",
    where: str = "top",
    log: bool = True,
    size: int = 10,
    x: float = 1.0,
    color: str | None = None,
) -> dict:
    """Annotation dict: ``text`` on a horizontal line at ``y`` (log axis: plotly takes log10 y), at ``x`` of the
    plot's width (1: right end, 0: left end, 0.5: middle), optionally in ``color``."""
    anchor = {1.0: "right", 0.0: "left"}.get(float(x), "center")
    font = dict(size=size) if color is None else dict(size=size, color=color)
    return dict(
        xref="x domain",
        x=x,
        xanchor=anchor,
        yref=yaxis,
        y=float(np.log10(y)) if log else float(y),
        yanchor="bottom" if where == "top" else "top",
        showarrow=False,
        text=text,
        font=font,
    )


def move_current_bits(fig: go.Figure, current_bits: int) -> go.Figure:
    """Move the dotted current-b marker(s) drawn by :func:`mark_bits` to ``current_bits``, in place.

    A cheap redraw for the dashboard when only b changed (the curves stay). Figures
    built without ``current_bits`` have no marker and are returned unchanged.
    """
    for shape in fig.layout.shapes:
        if shape.name == CURRENT_B:
            shape.x0 = shape.x1 = current_bits
    return fig


def has_current_bits(fig: go.Figure) -> bool:
    """Whether ``fig`` has a current-b marker (drawn by :func:`mark_bits`)."""
    layout = getattr(fig, "_layout", None)  # (plotly's own dict: read without validating every shape)
    if not isinstance(layout, dict):
        return any(shape.name == CURRENT_B for shape in fig.layout.shapes)
    return any(isinstance(s, dict) and s.get("name") == CURRENT_B for s in layout.get("shapes") or ())


def with_current_bits(fig: go.Figure, current_bits: int) -> go.Figure:
    """A copy of ``fig`` with its current-b marker(s) at ``current_bits``; ``fig`` is left as it is (other tabs may
    draw it). The copy is made from the figure's own dicts, unvalidated (as :func:`app.figures.raw.figure`), and
    shares its resolved template."""
    data, layout = getattr(fig, "_data", None), getattr(fig, "_layout", None)
    if not isinstance(data, list) or not isinstance(layout, dict):
        return move_current_bits(go.Figure(fig), current_bits)
    template = layout.get("template")
    out = go.Figure(dict(data=data, layout={k: v for k, v in layout.items() if k != "template"}), _validate=False)
    if template is not None:
        out._layout["template"] = template
    return move_current_bits(out, current_bits)


class MarkedAt:
    """Figure ``base`` with its current-b marker(s) at ``bits``, as handed to a plot handle (like
    :class:`app.figures.raw.Wire`, whose ``to_json`` viser calls): its JSON is written from ``base``'s own dicts
    with the markers' shapes replaced, so ``base`` is left as it is (other tabs may draw it) and nothing is
    copied; the moved figure itself (:func:`with_current_bits`) is made only if read (``.figure``, ``.layout``,
    ...)."""

    __slots__ = ("base", "bits", "_figure")

    def __init__(self, base: go.Figure, bits: int):
        self.base, self.bits = base, bits
        self._figure: go.Figure | None = None

    @property
    def figure(self) -> go.Figure:
        if self._figure is None:
            self._figure = with_current_bits(self.base, self.bits)
        return self._figure

    def to_json(self) -> str:
        layout = getattr(self.base, "_layout", None)
        if not isinstance(layout, dict):
            return to_json(self.figure)
        shapes = [
            {**s, "x0": self.bits, "x1": self.bits} if isinstance(s, dict) and s.get("name") == CURRENT_B else s
            for s in layout.get("shapes") or ()
        ]
        return to_json(self.base, {"shapes": shapes} if shapes else None)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.figure, name)
