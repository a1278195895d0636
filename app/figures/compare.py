"""Comparison: a pinned earlier result overlaid (dashed) on the curves, and phase portraits at several b.

* :func:`overlay_pinned` copies the line traces of a view built for the pinned
  frame into the current figure, dashed and named "(pinned)": the error, cost and
  bound plots (:data:`PINNED_VIEWS`) show both until the pin is released.
* :data:`VIEW` draws the closed loops at several word lengths (default 2, 4, 6,
  as the letter's figures (d)-(f)) side by side, projected on two states (the
  first two of the 3-D view's axes), LS blue, BCLS red, true model black.
"""

from __future__ import annotations

from collections.abc import Container
from typing import Any

import numpy as np
import plotly.graph_objects as go
from numpy.typing import NDArray

from .palette import COLORS, color, pinned_color
from .phase_scene import axes_indices
from .raw import arr, figure
from .view import CURVES, FrameView, View

__all__ = ["PINNED_VIEWS", "overlay_pinned", "parse_bits", "portraits_figure", "VIEW"]

#: The views that show a pinned result as dashed lines.
PINNED_VIEWS = ("error", "cost", "bound")
#: Word lengths of the portraits when none usable is typed (the letter's figures (d)-(f)).
DEFAULT_BITS = (2, 4, 6)
#: Legend groups of reference lines, not measurements: not copied by :func:`overlay_pinned`.
REFERENCE_GROUPS = ("ref", "th", "thx")


def overlay_pinned(fig: go.Figure, pinned_fig: go.Figure, label: str) -> go.Figure:
    """Add the line traces of ``pinned_fig`` to ``fig`` (in place): dashed, in the pinned colour of their live
    colour (:func:`~app.figures.palette.pinned_color`), named "<name> (label)"."""
    for tr in pinned_fig.data:
        if getattr(tr, "fill", None) in ("toself", "tonexty") or tr.type != "scatter":
            continue  # bands and bars stay with the live figure
        if tr.mode == "markers" or tr.legendgroup in REFERENCE_GROUPS:
            continue  # marks and reference lines (slope, Theorem 1) would only double the legend
        d = tr.to_plotly_json()
        line = d.get("line") or {}
        c = pinned_color(line.get("color") or (d.get("marker") or {}).get("color") or "")
        d["line"] = {**line, "dash": "dash", "width": 1.5, "color": c}
        d["marker"] = {**(d.get("marker") or {}), "symbol": "circle-open", "color": c}
        d["name"] = f"{d.get('name', '')} ({label})"
        d["legendgroup"] = f"pinned {d.get('legendgroup', d['name'])}"
        d["opacity"] = 0.75
        d.pop("error_y", None)
        fig.add_trace(d)
    return fig


def parse_bits(text: str, allowed: Container[int]) -> tuple[tuple[int, ...], tuple[str, ...]]:
    """Word lengths typed as "2, 4, 6": (those in ``allowed``, the tokens ignored)."""
    ok: list[int] = []
    bad: list[str | int] = []
    for tok in str(text).replace(";", ",").replace(" ", ",").split(","):
        if not tok:
            continue
        try:
            b = int(tok)
        except ValueError:
            bad.append(tok)
            continue
        (ok if b in allowed and b not in ok else bad).append(b)
    return tuple(ok), tuple(str(x) for x in bad)


def _lines(
    states: NDArray[np.float64], i: int, j: int, xa: str, ya: str, c: str, name: str, legend: bool, w: float = 1.0
) -> dict[str, Any]:
    R = states.shape[0]
    gap = np.full((R, 1), np.nan)
    xs = np.hstack([states[:, :, i], gap]).reshape(-1)
    ys = np.hstack([states[:, :, j], gap]).reshape(-1)
    return dict(
        type="scatter",
        x=arr(xs),
        y=arr(ys),
        mode="lines",
        name=name,
        legendgroup=name,
        showlegend=legend,
        line=dict(color=c, width=w),
        opacity=0.6 if w < 1.5 else 1.0,
        xaxis=xa,
        yaxis=ya,
    )


def portraits_figure(
    loops: dict[int, dict[str, NDArray[np.float64]]],
    true_states: NDArray[np.float64] | None,
    dims: tuple[int, int],
    names: tuple[str, str],
    height: int = 320,
    note: str = "",
) -> go.Figure:
    """Side-by-side phase portraits.

    Parameters
    ----------
    loops : dict b -> {label: states (R, T+1, n)}
    true_states : ndarray (T+1, n) or None
        The true-model loop (the same at every b).
    dims : (i, j)
        State indices on the horizontal and vertical axes.
    names : (str, str)
        Their names.
    """
    k = max(1, len(loops))
    gap = 0.06
    w = (1 - gap * (k - 1)) / k
    data: list[dict[str, Any]] = []
    layout: dict[str, Any] = {}
    for p, (b, per) in enumerate(loops.items()):
        xa, ya = ("x", "y") if p == 0 else (f"x{p + 1}", f"y{p + 1}")
        lo = p * (w + gap)
        layout["xaxis" if p == 0 else f"xaxis{p + 1}"] = dict(
            domain=[lo, lo + w], anchor=ya, title=dict(text=f"{names[0]}  (b = {b})")
        )
        layout["yaxis" if p == 0 else f"yaxis{p + 1}"] = dict(anchor=xa, title=dict(text=names[1] if p == 0 else ""))
        for q, (label, st) in enumerate(per.items()):
            ok = np.all(np.isfinite(st.reshape(st.shape[0], -1)), axis=1)
            data.append(_lines(st[ok], *dims, xa, ya, color(label, q), label, p == 0))
        if true_states is not None:
            data.append(_lines(true_states[None], *dims, xa, ya, COLORS["true"], "true model", p == 0, w=1.5))
    layout.update(
        height=height,
        margin=dict(l=50, r=10, t=30, b=40),
        legend=dict(orientation="h", y=-0.3),
        title=dict(text=note or "closed loops at several word lengths", font=dict(size=11)),
    )
    return figure(data, layout)


def _build(frame: FrameView) -> go.Figure:
    ex = frame.ex
    assert ex is not None  # a frame the views draw holds its experiment
    bits, bad = parse_bits(frame.values.compare_bits, ex.config.bits)
    if not bits:  # nothing usable typed: the letter's word lengths, and the note says what was ignored
        bits = tuple(b for b in DEFAULT_BITS if b in ex.config.bits) or tuple(ex.config.bits[:1])
    names = frame.system.state_names
    i, j, _ = axes_indices(frame.values.axes, names)
    j = j if j is not None else i
    note = "phase portraits at b = " + ", ".join(map(str, bits))
    if bad:
        note += f" (ignored: {', '.join(bad)}; b must be one of {ex.config.bits[0]}..{ex.config.bits[-1]})"
    if not frame.complete:
        return portraits_figure({}, None, (i, j), (names[i], names[j]), note="waiting for every b to finish …")
    # closed loops of every b were computed for the curves: these are cache reads (label "LS" = estimator "ls")
    loops = {b: {lab: ex.closed_loops(b, lab.lower()).states for lab in frame.labels} for b in bits}
    true = frame.true_loop.states[0] if frame.true_loop is not None else None
    return portraits_figure(loops, true, (i, j), (names[i], names[j]), note=note)


VIEW = View("portraits", aspect=0.5, depends=CURVES, build=_build, tab="Compare")
