"""Helpers shared by the plot builders: reading rows, mean +- std bands, the current-b marker.

Inputs are plain data: *rows* are the JSON-ready per-b summaries of
:func:`qsid_core.sweep.summary_row` (the ``results`` entries of
``qsid sweep --json``); a *series* maps a label (``"LS"``, ``"BCLS"``) to a list
of rows. Missing values (``None``) are skipped, so partially filled sweeps draw.
The only arithmetic here is reshaping for display.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import plotly.graph_objects as go

from .palette import COLORS

__all__ = ["Rows", "Series", "get", "xy", "band", "mark_bits", "move_current_bits", "BITS_AXIS"]

Rows = Sequence[Mapping]
Series = Mapping[str, Rows]
#: x axis of every plot against the word length.
BITS_AXIS = dict(title_text="word length b [bits]", dtick=2)


def get(row: Mapping, *path):
    """``row[path[0]][path[1]]...``, None where a level is missing."""
    v = row
    for p in path:
        if v is None:
            return None
        v = v.get(p) if isinstance(v, Mapping) else None
    return v


def xy(rows: Rows, *path) -> tuple[list, list]:
    """(b, value) of every row whose value at ``path`` is finite and positive (log axes), sorted by b."""
    xs, ys = [], []
    for r in sorted(rows, key=lambda r: r["bits"]):
        v = get(r, *path)
        if v is not None and np.isfinite(v) and v > 0:
            xs.append(r["bits"])
            ys.append(float(v))
    return xs, ys


def band(fig, rows: Rows, key: str, color: str, name: str, row=None, col=None, showlegend=True) -> None:
    """Mean line with a mean +- std band (clipped above zero for the log axis)."""
    pts = []
    for r in sorted(rows, key=lambda r: r["bits"]):
        m, s = get(r, key, "mean"), get(r, key, "std")
        if m is not None and np.isfinite(m) and m > 0:
            pts.append((r["bits"], m, s or 0.0))
    if not pts:
        return
    b = [p[0] for p in pts]
    m = np.array([p[1] for p in pts])
    s = np.array([p[2] for p in pts])
    up = m + s
    lo = np.where(m - s > 0, m - s, m / 10)
    kw = {} if row is None else {"row": row, "col": col}
    fig.add_trace(go.Scatter(x=b + b[::-1], y=list(up) + list(lo[::-1]), fill="toself", fillcolor=color,
                             opacity=0.18, line=dict(width=0), hoverinfo="skip", showlegend=False,
                             legendgroup=name), **kw)
    fig.add_trace(go.Scatter(x=b, y=list(m), mode="lines+markers", name=name, legendgroup=name,
                             showlegend=showlegend, line=dict(color=color),
                             error_y=dict(type="data", array=list(s), visible=False)), **kw)


def mark_bits(fig, current_bits: int | None, **kw) -> None:
    """A dotted vertical line at the current word length (none if ``current_bits`` is None)."""
    if current_bits is not None:
        fig.add_vline(x=current_bits, line=dict(color=COLORS["marker"], dash="dot", width=1), **kw)


def move_current_bits(fig: go.Figure, current_bits: int) -> go.Figure:
    """Move the dotted current-b marker(s) drawn by :func:`mark_bits` to ``current_bits``, in place.

    A cheap redraw for the dashboard when only b changed (the curves stay). Figures
    built without ``current_bits`` have no marker and are returned unchanged.
    """
    for shape in fig.layout.shapes:
        if shape.x0 == shape.x1 and str(shape.yref or "").endswith("domain"):
            shape.x0 = shape.x1 = current_bits
    return fig
