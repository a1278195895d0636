"""What a plot draws, checked against itself: one checker for the figure tests, the dashboard's lessons and the
browser (not a test module: pytest collects nothing here).

:func:`traces` turns a figure (a ``go.Figure``, the dict plotly.js holds, or its ``data`` list as a browser's
``el.data`` gives it) into the trace dicts plotly.js draws (the dashboard's own JSON: NaN as None).
:func:`check_drawn` asserts what every trace of every view must satisfy whatever it shows:

* x and y (z in 3-D, a per-point ``text``) have the same length;
* error bars are as long as y and not negative;
* a filled band (``fill="toself"``) is a polygon out along its upper edge and back along its lower one, and it
  encloses each line of its legend group on the same axes at every x the line is drawn.

:func:`line` and :func:`band_edges` read a trace back as numbers for the value checks of each view.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

__all__ = ["traces", "check_drawn", "line", "band_edges", "named", "values"]

#: Relative slack of "encloses" (the band and its line are computed from the same floats).
RTOL = 1e-9


def traces(fig: Any) -> list[dict[str, Any]]:
    """The trace dicts of ``fig`` as plotly.js receives them (a ``go.Figure``, ``{"data": [...]}`` or a list)."""
    if isinstance(fig, list):
        return fig
    if isinstance(fig, dict):
        return list(fig.get("data") or [])
    from app.figures.raw import to_json

    return list(json.loads(to_json(fig))["data"])


def values(v: Any) -> np.ndarray:
    """A trace's array as floats (None -> NaN)."""
    if v is None:
        return np.zeros(0)
    if isinstance(v, dict) and "bdata" in v:  # plotly's typed-array JSON
        import base64

        return np.frombuffer(base64.b64decode(v["bdata"]), dtype=np.dtype(v["dtype"])).astype(float)
    return np.array([np.nan if x is None else x for x in v], dtype=float)


def _axes(tr: dict[str, Any]) -> tuple[str, str]:
    return tr.get("xaxis") or "x", tr.get("yaxis") or "y"


def _where(view: str, i: int, tr: dict[str, Any]) -> str:
    return f"{view}: trace {i} ({tr.get('type', 'scatter')} {tr.get('name')!r})"


def band_edges(tr: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(x, upper, lower)`` of a filled band drawn out along one edge and back along the other."""
    x, y = values(tr.get("x")), values(tr.get("y"))
    h = len(x) // 2
    return x[:h], y[:h], y[h:][::-1]


def _check_band(view: str, i: int, tr: dict[str, Any], data: list[dict[str, Any]]) -> None:
    where = _where(view, i, tr)
    x = values(tr.get("x"))
    assert len(x) % 2 == 0, f"{where}: a band's polygon has an odd number of points ({len(x)})"
    bx, hi, lo = band_edges(tr)
    back = x[len(bx) :][::-1]
    assert np.array_equal(bx, back, equal_nan=True), f"{where}: the band does not come back along the same x"
    group, axes = tr.get("legendgroup"), _axes(tr)
    partners = [
        (j, t)
        for j, t in enumerate(data)
        if t is not tr
        and not t.get("fill")
        and t.get("legendgroup") == group
        and _axes(t) == axes
        and "lines" in str(t.get("mode", "lines"))
    ]
    assert partners, f"{where}: a band without its line (legend group {group!r}, axes {axes})"
    top, bottom = np.fmax(hi, lo), np.fmin(hi, lo)
    at = {float(b): k for k, b in enumerate(bx) if np.isfinite(b)}
    for j, t in partners:
        lx, ly = values(t.get("x")), values(t.get("y"))
        for xv, yv in zip(lx, ly):
            if not (np.isfinite(xv) and np.isfinite(yv)):
                continue
            k = at.get(float(xv))
            assert k is not None, f"{where}: no band at x = {xv} where trace {j} ({t.get('name')!r}) is drawn"
            a, b = bottom[k], top[k]
            assert np.isfinite(a) and np.isfinite(b), f"{where}: the band has a gap at x = {xv} under trace {j}"
            slack = RTOL * max(abs(a), abs(b), abs(yv))
            assert a - slack <= yv <= b + slack, (
                f"{where}: at x = {xv} the band [{a:.6g}, {b:.6g}] does not enclose trace {j} "
                f"({t.get('name')!r}) = {yv:.6g}"
            )


def check_drawn(fig: Any, view: str = "figure") -> list[dict[str, Any]]:
    """Assert the drawn data of ``fig`` is consistent (see the module docstring); returns its trace dicts."""
    data = traces(fig)
    for i, tr in enumerate(data):
        where = _where(view, i, tr)
        if "x" in tr and "y" in tr:
            nx, ny = len(values(tr["x"])), len(values(tr["y"]))
            assert nx == ny, f"{where}: {nx} x values against {ny} y values"
            if "z" in tr and tr.get("type") == "scatter3d":
                nz = len(values(tr["z"]))
                assert nz == nx, f"{where}: {nz} z values against {nx} x values"
            text = tr.get("text")
            if isinstance(text, list):
                assert len(text) == ny, f"{where}: {len(text)} hover texts against {ny} points"
            for key in ("error_y", "error_x"):
                err = tr.get(key) or {}
                for arr_key in ("array", "arrayminus"):
                    if err.get(arr_key) is None:
                        continue
                    e = values(err[arr_key])
                    assert len(e) == ny, f"{where}: {key}.{arr_key} has {len(e)} values against {ny} points"
                    assert np.all(e[np.isfinite(e)] >= 0), f"{where}: a negative {key}.{arr_key}"
        if tr.get("fill") == "toself":
            _check_band(view, i, tr, data)
    return data


def named(data: list[dict[str, Any]], name: str, xaxis: str | None = None) -> list[dict[str, Any]]:
    """The traces called ``name`` (on x axis ``xaxis`` if given)."""
    return [t for t in data if t.get("name") == name and (xaxis is None or _axes(t)[0] == xaxis)]


def line(data: list[dict[str, Any]], name: str, xaxis: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(x, y)`` of the one trace called ``name`` (on ``xaxis``)."""
    found = named(data, name, xaxis)
    assert len(found) == 1, (
        f"{len(found)} traces called {name!r} on {xaxis or 'any axis'}: {[t.get('name') for t in data]}"
    )
    return values(found[0].get("x")), values(found[0].get("y"))
