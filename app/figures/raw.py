"""Plotly figures from plain dicts, without plotly's per-property validation (5-10x faster to build).

The dashboard rebuilds the current-b views on every b change; a validated
``make_subplots`` figure of 15 traces takes ~150-400 ms here, the same figure as
dicts ~10-20 ms (``benchmarks/bench_dashboard.py`` prints the per-view times).
Only use it for figures whose keys are known to be valid (the tests build them).
"""

from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np
import orjson
import plotly.graph_objects as go
import plotly.io as pio
from numpy.typing import ArrayLike

__all__ = ["figure", "stacked_axes", "arr", "hline", "to_json", "Wire", "PLOT_CONFIG"]

_JSON_OPTIONS = orjson.OPT_SERIALIZE_NUMPY | orjson.OPT_NON_STR_KEYS


@cache
def _template(name: str) -> dict:
    return pio.templates[name].to_plotly_json()


def arr(a: ArrayLike) -> np.ndarray:
    """A numeric array as a flat float array for a trace, every non-finite value NaN (a gap in a line).

    An array, not a list: plotly copies each trace's data when a figure is made, which for a list is a
    Python object per point; the JSON (:func:`to_json`, or plotly's own) writes NaN as a gap."""
    x = np.array(a, dtype=float).reshape(-1)
    x[~np.isfinite(x)] = np.nan
    return x


def figure(data: list, layout: dict, template: str = "plotly_white") -> go.Figure:
    """``go.Figure`` of ``data`` (trace dicts) and ``layout`` (dict), unvalidated, with a resolved template."""
    return go.Figure(dict(data=data, layout={"template": _template(template), **layout}), _validate=False)


def stacked_axes(rows: int, gap: float = 0.02, x_title: str = "") -> tuple[dict[str, Any], list[str]]:
    """Layout of ``rows`` subplots stacked over one shared x axis; returns (layout dict, y-axis ids "y", "y2", ...)."""
    h = (1.0 - gap * (rows - 1)) / rows
    lay: dict[str, Any] = {}
    ids: list[str] = []
    for k in range(rows):
        top = 1.0 - k * (h + gap)
        name = "yaxis" if k == 0 else f"yaxis{k + 1}"
        lay[name] = dict(domain=[max(0.0, top - h), top], anchor="x")
        ids.append("y" if k == 0 else f"y{k + 1}")
    lay["xaxis"] = dict(anchor=ids[-1], title=dict(text=x_title))
    return lay, ids


def hline(y: float, yaxis: str, color: str, dash: str = "dash", width: float = 1.0) -> dict:
    """A horizontal line across the plot at ``y`` on axis ``yaxis`` (a layout shape)."""
    return dict(
        type="line", xref="x domain", x0=0, x1=1, yref=yaxis, y0=y, y1=y, line=dict(color=color, dash=dash, width=width)
    )


def _json_default(o: object) -> Any:
    if isinstance(o, np.ndarray):  # non-contiguous or of a dtype orjson does not take
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"not JSON serializable: {type(o).__name__}")


#: plotly.js's options for every plot the dashboard draws: no tool bar (it covered the first line of a title, and
#: offered an upload to a cloud service, "Share chart…"); dragging still zooms and a double click resets, and the
#: panel's "Export figures (HTML, offline)" keeps a copy. The cloud buttons are off even where a bar is shown.
PLOT_CONFIG: dict[str, Any] = {
    "displayModeBar": False,
    "showSendToCloud": False,
    "showEditInChartStudio": False,
    "displaylogo": False,
    "modeBarButtonsToRemove": ["sendDataToCloud", "editInChartStudio", "lasso2d", "select2d"],
}


def to_json(fig: go.Figure, layout_items: dict[str, Any] | None = None) -> str:
    """The figure's JSON as plotly.js takes it, without ``Figure.to_json``'s deep copy and base64 pass
    (``layout_items``: layout entries written instead of the figure's, which is left as it is).

    ``go.Figure.to_json`` deep-copies the whole figure (template included) and
    re-encodes every array; on a b change that was about half of the dashboard's
    redraw time. This reads the figure's own data and layout (plotly keeps them as
    plain dicts) and writes them with orjson: arrays as lists, NaN and inf as null
    (strict JSON; plotly.js draws a gap).
    """
    data, layout = getattr(fig, "_data", None), getattr(fig, "_layout", None)
    if not isinstance(data, list) or not isinstance(layout, dict):
        d = orjson.loads(fig.to_json())
        data, layout = d["data"], d["layout"]
    if layout_items:
        layout = {**layout, **layout_items}
    return orjson.dumps(
        {"data": data, "layout": layout, "config": PLOT_CONFIG}, option=_JSON_OPTIONS, default=_json_default
    ).decode()


class Wire:
    """A figure handed to viser's plot handle (``handle.figure = Wire(fig)``): viser calls :meth:`to_json`.

    Everything else (``.data``, ``.layout``, ...) is the wrapped figure's, so code and
    tests that read ``handle.figure`` see the plotly figure.
    """

    __slots__ = ("figure",)

    def __init__(self, figure: go.Figure):
        self.figure = figure

    def to_json(self) -> str:
        return to_json(self.figure)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.figure, name)
