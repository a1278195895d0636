"""View (nonlinear plants): the relative error of the lifted model [A_z, B_z] against the unquantized EDMD of the
same data, per word length: LS and BCLS with their spread, and LS's large-data limit where it holds.

The large-data limit (:func:`qsid_core.identification.large_data_limit`, the lifted Theorem 1) is exact for a
polynomial dictionary with subtractive dither and no overload; where a hypothesis fails (radial functions, other
dither, samples past the range) the line is not drawn and the plot says why.
"""

from __future__ import annotations

from typing import Any

import plotly.graph_objects as go

from .hypotheses import bits_text
from .palette import COLORS, color
from .raw import figure
from .traces import band, mark_bits, xy
from .view import CURVES, View

__all__ = ["VIEW", "error_figure", "limit_note"]


def limit_note(rows: dict[str, list[dict[str, Any]]], guard: bool) -> str:
    """Why LS's large-data limit is not drawn ("" when it is drawn for every b shown)."""
    notes = {(r.get("large_data") or {}).get("note", "") for r in rows.get("LS", [])}
    notes.discard("")
    if notes:
        return sorted(notes)[0]
    ls = rows.get("LS", [])
    over = [r["bits"] for r in ls if r.get("overload_fraction", 0.0) > 0]
    if over and not guard:
        where = "every b" if len(over) == len(ls) else bits_text(over)
        return f"samples past the range at {where}; it assumes none (tick the guard band)"
    return ""


def error_figure(
    rows: dict[str, list[dict[str, Any]]], bits: int | None, guard: bool = True, height: int = 330
) -> go.Figure:
    """log error of [A_z, B_z] vs b for each estimator label in ``rows`` (mean with a ±std band), LS's
    large-data limit dashed where its hypotheses hold."""
    data: list[dict[str, Any]] = []
    for i, (lab, rs) in enumerate(rows.items()):
        data += band(rs, "err_G", color(lab, i), f"{lab}: quantized EDMD")
    note = limit_note(rows, guard)
    if "LS" in rows and not note:
        xs, ys = xy(rows["LS"], "large_data", "err_G")
        if xs:
            data.append(
                dict(
                    type="scatter",
                    x=xs,
                    y=ys,
                    mode="lines",
                    name="LS large-data limit",
                    line=dict(color=COLORS["theory"], dash="dash", width=2),
                )
            )
    annotations = []
    if note:
        annotations.append(
            dict(
                xref="paper",
                yref="paper",
                x=0.0,
                y=1.0,
                xanchor="left",
                yanchor="bottom",
                showarrow=False,
                text="no large-data limit: " + note[:80] + ("…" if len(note) > 80 else ""),
                font=dict(size=11),
            )
        )
    return figure(
        data,
        dict(
            height=height,
            margin=dict(l=60, r=10, t=34, b=40),
            legend=dict(orientation="h", y=-0.22),
            xaxis=dict(title=dict(text="word length b (bits)"), dtick=2),
            yaxis=dict(title=dict(text="error of [A_z, B_z] vs EDMD"), type="log", exponentformat="power"),
            shapes=mark_bits(bits),
            annotations=annotations,
        ),
    )


def _build(frame: Any) -> go.Figure:
    return error_figure(frame.series(), frame.bits, bool(frame.values.guard))


VIEW = View("koopman-error", aspect=0.62, depends=CURVES, build=_build, tab="Nonlinear")
