"""View: relative errors of A^ and B^ against the data length T at the current b (log-log).

LS and BCLS mean +- std over dither realizations, Theorem 1's large-data
prediction (the floor LS levels off on), and a T^-1/2 reference through the
first LS point. The rows are :func:`qsid_core.studies.datalength.run_datalength`'s
(``DataLengthRow.to_dict()``); the study runs on demand (button in the tab), so
without a result the view says how to start it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import plotly.graph_objects as go

from .palette import COLORS, color
from .raw import arr, figure
from .view import CURRENT, FrameView, View

__all__ = ["datalength_figure", "VIEW"]


def _panel(rows: list[dict[str, Any]], key: str, xa: str, ya: str, legend: bool) -> list[dict[str, Any]]:
    T = np.array([r["samples"] for r in rows], dtype=float)
    data: list[dict[str, Any]] = []
    for i, est in enumerate(("ls", "bcls")):
        lab = est.upper()
        m = np.array([np.nan if r[est][key]["mean"] is None else r[est][key]["mean"] for r in rows], dtype=float)
        s = np.array([0.0 if r[est][key]["std"] is None else r[est][key]["std"] for r in rows], dtype=float)
        lo = np.where(m - s > 0, m - s, m / 10)
        data.append(
            dict(
                type="scatter",
                x=arr(np.concatenate([T, T[::-1]])),
                y=arr(np.concatenate([m + s, lo[::-1]])),
                fill="toself",
                fillcolor=color(lab, i),
                opacity=0.18,
                line=dict(width=0),
                hoverinfo="skip",
                showlegend=False,
                legendgroup=lab,
                xaxis=xa,
                yaxis=ya,
            )
        )
        data.append(
            dict(
                type="scatter",
                x=arr(T),
                y=arr(m),
                mode="lines+markers",
                name=f"{lab} mean ± std",
                legendgroup=lab,
                showlegend=legend,
                line=dict(color=color(lab, i)),
                xaxis=xa,
                yaxis=ya,
            )
        )
    th = [r[f"{key}_theory"] for r in rows]
    data.append(
        dict(
            type="scatter",
            x=arr(T),
            y=arr([np.nan if v is None else v for v in th]),
            mode="lines",
            name="Theorem 1 (large T)",
            legendgroup="th",
            showlegend=legend,
            line=dict(color=COLORS["theory"], dash="dash"),
            xaxis=xa,
            yaxis=ya,
        )
    )
    ls0 = rows[0]["ls"][key]["mean"]
    if ls0:
        data.append(
            dict(
                type="scatter",
                x=arr(T),
                y=arr(ls0 * np.sqrt(T[0] / T)),
                mode="lines",
                name="∝ T^-1/2",
                legendgroup="ref",
                showlegend=legend,
                line=dict(color=COLORS["ref"], dash="dot"),
                xaxis=xa,
                yaxis=ya,
            )
        )
    return data


def datalength_figure(result: dict[str, Any] | None, bits: int, height: int = 340, note: str = "") -> go.Figure:
    """Two log-log panels (‖ΔA‖/‖A‖, ‖ΔB‖/‖B‖) against T from ``result`` (``DataLengthResult.to_dict()``)."""
    res = result or {}
    rows = res.get("rows") or []
    layout = dict(
        xaxis=dict(domain=[0, 0.46], type="log", title=dict(text="samples T"), anchor="y", exponentformat="power"),
        xaxis2=dict(domain=[0.54, 1], type="log", title=dict(text="samples T"), anchor="y2", exponentformat="power"),
        yaxis=dict(type="log", anchor="x", title=dict(text="‖ΔA‖/‖A‖"), exponentformat="power"),
        yaxis2=dict(type="log", anchor="x2", title=dict(text="‖ΔB‖/‖B‖"), exponentformat="power"),
        height=height,
        margin=dict(l=55, r=10, t=40, b=40),
        legend=dict(orientation="h", y=-0.3),
    )
    if not rows:
        layout["annotations"] = [
            dict(
                text=note or "press “Compute error vs data length”",
                showarrow=False,
                x=0.5,
                y=0.5,
                xref="paper",
                yref="paper",
            )
        ]
        layout["title"] = dict(text=f"error vs data length at b = {bits}", font=dict(size=11))
        for key in ("xaxis", "xaxis2", "yaxis", "yaxis2"):  # no data yet: no empty axes whose labels collide
            axis = layout[key]
            assert isinstance(axis, dict)
            axis["visible"] = False
        return figure([], layout)
    data = _panel(rows, "err_A", "x", "y", True) + _panel(rows, "err_B", "x2", "y2", False)
    cfg = res.get("config", {})
    layout["title"] = dict(
        text=(
            f"error vs data length at b = {res.get('bits', bits)} · "
            f"{cfg.get('realizations', '?')} realizations · {note}"
        ).rstrip(" ·"),
        font=dict(size=11),
    )
    return figure(data, layout)


def _build(frame: FrameView) -> go.Figure:
    res = frame.datalength
    return datalength_figure(None if res is None else res.to_dict(), frame.bits)


VIEW = View(
    "datalength",
    aspect=0.6,
    depends=CURRENT,
    build=_build,
    tab="Data length",
    key=lambda frame: (frame.bits, id(frame.datalength)),
)
