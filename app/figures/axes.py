"""Axis ranges that cannot blow up: every 2-D axis range from the finite data drawn on it.

:func:`finite_axes` is applied to every dashboard figure (by
:func:`app.frames.render.build_figures`), so a new view gets it for free.
Rules (log axes in decades, plotly's own unit for log ranges):

* only finite numbers count (and only positive ones on a log axis);
* a log axis spans at most :data:`MAX_DECADES`; if the data span more, the
  window holding the most points is kept and the axis title says that values
  lie off the axis (e.g. diverged closed loops with cost 1e289);
* a log axis spans at least :data:`MIN_DECADES` and, while it spans fewer than
  2.5 decades, is ticked at 1, 2, 5 per decade with full labels (0.5, not plotly's bare "5";
  no crowded "10 9 8 .. 2 1"): :func:`log_ticks`;
* a margin of :data:`MARGIN` of the span on each side.

Only reshaping for display: nothing is computed from the numbers but their extent.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
import plotly.graph_objects as go
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "finite_axes",
    "axis_ranges",
    "top_log_range",
    "log_ticks",
    "tick_label",
    "MAX_DECADES",
    "MIN_DECADES",
    "MARGIN",
]

#: Largest span of a log axis (decades).
MAX_DECADES = 12.0
#: Smallest span of a log axis (decades).
MIN_DECADES = 1.0
#: Margin on each side, as a share of the span.
MARGIN = 0.05


#: element types converted in one numpy call (bool is not among them: True is no data value)
_PLAIN = {float, int, type(None), np.float64, np.float32, np.int64, np.int32}


def _numbers(seq: ArrayLike | None) -> NDArray[np.float64]:
    """Finite floats of a plotly data array (None, strings and non-finite values dropped)."""
    if seq is None:
        return np.zeros(0)
    a = seq if isinstance(seq, np.ndarray) and seq.dtype.kind in "fiu" else np.asarray(seq, dtype=object)
    if a.dtype.kind in "fiu" or set(map(type, a.reshape(-1).tolist())) <= _PLAIN:
        f = a.astype(float).reshape(-1)  # None -> NaN
        return f[np.isfinite(f)]
    out = []
    for v in np.asarray(seq, dtype=object).reshape(-1):
        if isinstance(v, (bool, np.bool_)) or v is None:
            continue
        try:
            fv = float(v)
        except (TypeError, ValueError):
            continue
        if np.isfinite(fv):
            out.append(fv)
    return np.asarray(out, dtype=float)


def _axis_name(ref: str | None, letter: str) -> str:
    """Trace/shape reference ('x', 'x2', 'y3 domain') -> layout key ('xaxis', 'xaxis2')."""
    ref = (ref or letter).split(" ")[0]
    return f"{letter}axis{ref[1:]}"


def _collect(fig: go.Figure) -> dict[str, NDArray[np.float64]]:
    """layout axis key -> finite data drawn on it (traces, and lines drawn in data units).

    Each trace and shape is read once as a plain dict (``to_plotly_json``): plotly validates every property
    read, which for a figure of 25 traces cost more than the rest of this module."""
    data: dict[str, list[NDArray[np.float64]]] = {}
    for tr in fig.data:
        if not hasattr(type(tr), "xaxis") or not hasattr(type(tr), "y"):  # a trace kind without 2-D axes
            continue
        d = tr.to_plotly_json()
        for letter in ("x", "y"):
            key = _axis_name(d.get(f"{letter}axis"), letter)
            data.setdefault(key, []).append(_numbers(d.get(letter)))
    for sh in fig.layout.shapes or ():
        d = sh.to_plotly_json()
        for letter in ("x", "y"):
            ref = d.get(f"{letter}ref") or letter
            if ref in ("paper",) or ref.endswith("domain"):
                continue
            key = _axis_name(ref, letter)
            data.setdefault(key, []).append(_numbers([d.get(f"{letter}0"), d.get(f"{letter}1")]))
    return {k: np.concatenate(v) if v else np.zeros(0) for k, v in data.items()}


def _log_range(vals: NDArray[np.float64], max_dec: float) -> tuple[list[float], bool]:
    """(range in decades, some data off the axis)."""
    L = np.sort(np.log10(vals[vals > 0]))
    width = max_dec / (1 + 2 * MARGIN)
    lo, hi = float(L[0]), float(L[-1])
    off = False
    if hi - lo > width:  # the window of `width` decades holding the most points
        j = np.searchsorted(L, L + width, side="right")
        i = int(np.argmax(j - np.arange(L.size)))
        lo, hi, off = float(L[i]), float(L[i]) + width, True
    if hi - lo < MIN_DECADES:
        mid = 0.5 * (hi + lo)
        lo, hi = mid - MIN_DECADES / 2, mid + MIN_DECADES / 2
    pad = MARGIN * (hi - lo)
    return [lo - pad, hi + pad], off


def _lin_range(vals: NDArray[np.float64]) -> list[float]:
    lo, hi = float(vals.min()), float(vals.max())
    if hi - lo <= 1e-12 * max(abs(lo), abs(hi), 1e-300):
        half = 0.1 * abs(lo) if lo != 0 else 1.0
        lo, hi = lo - half, hi + half
    pad = MARGIN * (hi - lo)
    return [lo - pad, hi + pad]


def _logs(values: Iterable[float | None]) -> NDArray[np.float64]:
    v = np.asarray([x for x in values if x is not None], dtype=float)
    return np.log10(v[np.isfinite(v) & (v > 0)])


def top_log_range(values: Iterable[float | None], keep: Sequence[float | None] = ()) -> list[float] | None:
    """A log axis range (decades) of at most MAX_DECADES that always shows ``keep``, then the top of ``values``.

    For views whose point is a few lines (bounds, starting norms) while other values lie
    far below or above: the generic rule (:func:`finite_axes`) keeps the window holding
    the most points, which can be converged tails, and cut the bounds off. Here the
    window covers ``keep`` (its top part if ``keep`` alone spans more), then grows up
    to the largest of ``values``, then down. None if nothing is finite and positive.
    """
    width = MAX_DECADES / (1 + 2 * MARGIN)
    allv, k = _logs(list(values) + list(keep)), _logs(keep)
    if allv.size == 0:
        return None
    if k.size == 0:
        k = allv[[np.argmax(allv)]]
    lo, hi = float(k.min()), float(k.max())
    lo = max(lo, hi - width)
    hi = min(float(allv.max()), lo + width) if allv.max() > hi else hi
    lo = max(float(allv.min()), hi - width) if allv.min() < lo else lo
    if hi - lo < MIN_DECADES:
        lo, hi = 0.5 * (lo + hi) - MIN_DECADES / 2, 0.5 * (lo + hi) + MIN_DECADES / 2
    pad = MARGIN * (hi - lo)
    return [lo - pad, hi + pad]


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def tick_label(v: float) -> str:
    """A full tick label: '0.5', '20', '2×10⁻⁵' (plain digits between 10⁻³ and 10⁴, a power of ten outside)."""
    e = int(np.floor(np.log10(v) + 1e-9))
    m = round(v / 10.0**e, 6)
    if -3 <= e <= 3:
        return f"{v:.{max(0, -e)}f}" if e < 0 else f"{v:g}"
    power = "10" + str(e).translate(_SUPERSCRIPT)
    return power if m == 1 else f"{m:g}×{power}"


def log_ticks(rng: Sequence[float]) -> dict:
    """``tickvals``/``ticktext`` at 1, 2 and 5 per decade inside ``rng`` (log10 units, plotly's log range)."""
    vals = [
        m * 10.0**e
        for e in range(int(np.floor(rng[0])), int(np.ceil(rng[1])) + 1)
        for m in (1, 2, 5)
        if rng[0] <= np.log10(m) + e <= rng[1]
    ]
    return dict(tickvals=vals, ticktext=[tick_label(v) for v in vals])


def finite_axes(fig: go.Figure, max_decades: float = MAX_DECADES) -> go.Figure:
    """Set every 2-D axis range of ``fig`` from its finite data (rules: module docstring); in place.

    Axes with an explicit range keep it; axes without numeric data are left alone.
    """
    for key, vals in _collect(fig).items():
        try:
            ax = fig.layout[key]
        except (KeyError, ValueError):  # not an axis plotly knows
            continue
        if ax.range is not None:
            continue
        log = ax.type == "log"
        if log:
            vals = vals[vals > 0]
        if vals.size == 0:
            continue
        # properties set one by one: Layout.update's batch machinery cost ~2 ms an axis
        if log:
            rng, off = _log_range(vals, max_decades)
            ax.range, ax.autorange = rng, False
            if rng[1] - rng[0] < 2.5:
                ticks = log_ticks(rng)
                ax.tickvals, ax.ticktext, ax.tickmode = ticks["tickvals"], ticks["ticktext"], "array"
            if off:
                title = ax.title.text or ""
                ax.title.text = (title + " " if title else "") + "(some values off the axis)"
        else:
            ax.range, ax.autorange = _lin_range(vals), False
    return fig


def axis_ranges(fig: go.Figure) -> dict[str, tuple[str, tuple[float, ...] | None]]:
    """layout axis key -> (type, range) of every 2-D axis with data (for tests and checks)."""
    out: dict[str, tuple[str, tuple[float, ...] | None]] = {}
    for key in _collect(fig):
        if key in fig.layout:
            ax = fig.layout[key]
            out[key] = (ax.type or "linear", None if ax.range is None else tuple(ax.range))
    return out
