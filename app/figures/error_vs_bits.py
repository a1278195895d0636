"""View: relative errors of A^ and B^ against the word length b (the letter's panels (a), (b)).

For a nonlinear plant (:data:`LIFTED_VIEW`, :func:`lifted_error_figure`): the relative error of the lifted model [A_z, B_z] against the unquantized EDMD of the
same data, per word length: LS and BCLS with their spread, and LS's large-data limit where it holds.

The large-data limit (:func:`qsid_core.identification.large_data_limit`, the lifted Theorem 1) is exact for a
polynomial dictionary with subtractive dither and no overload; where a hypothesis fails (radial functions, other
dither, samples past the range) the line is not drawn and the plot says why.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
import plotly.graph_objects as go

from qsid_core import fit_slope

from .hypotheses import bcls_reasons, bits_text, fits_reasons, flags, line_holds, theorem1_reasons
from .palette import COLORS, color
from .presenter import HOVER_HERE
from .raw import figure
from .traces import BITS_AXIS, Rows, Series, band, get, mark_bits, xy
from .view import CURVES, View

__all__ = ["error_figure", "lifted_error_figure", "limit_note", "slope_text", "LETTER_SLOPES", "LIFTED_VIEW", "VIEW"]


def _holds(rows: Rows, key: str = "theorem1_holds") -> dict[int, bool]:
    """b -> whether the engine says the hypotheses hold (True where the row has no assumptions)."""
    return {r["bits"]: bool((flags(r) or {}).get(key, True)) for r in rows}


def _axes(col: int) -> dict[str, str]:
    return dict(xaxis="x" if col == 1 else f"x{col}", yaxis="y" if col == 1 else f"y{col}")


def _theorem1(
    rows: Rows, key: str, col: int, name: str = "Theorem 1", line_color: str = COLORS["theory"]
) -> list[dict[str, Any]]:
    """Theorem 1's line for this panel's block: dashed where it applies (or fits), faded and dotted elsewhere."""
    tx, ty = xy(rows, f"{key}_theory")
    ok = {r["bits"]: line_holds(r, key[-1]) for r in rows}
    # the faded part also takes the neighbours of a failing b, so the two parts join up
    good = [y if ok[b] else None for b, y in zip(tx, ty)]
    bad = [
        y if not ok[b] or (i > 0 and not ok[tx[i - 1]]) or (i + 1 < len(tx) and not ok[tx[i + 1]]) else None
        for i, (b, y) in enumerate(zip(tx, ty))
    ]
    out = []
    if any(v is not None for v in good):
        out.append(
            dict(
                type="scatter",
                x=tx,
                y=good,
                mode="lines",
                name=name,
                legendgroup="th" if name == "Theorem 1" else f"th {name}",
                showlegend=(col == 1),
                connectgaps=False,
                line=dict(color=line_color, dash="dash"),
                **_axes(col),
            )
        )
    if any(v is not None for v in bad) and not all(ok[b] for b in tx):
        out.append(
            dict(
                type="scatter",
                x=tx,
                y=bad,
                mode="lines",
                name=f"{name} (hypotheses fail)",
                legendgroup="thx" if name == "Theorem 1" else f"thx {name}",
                showlegend=(col == 1),
                connectgaps=False,
                opacity=0.35,
                line=dict(color=line_color, dash="dot", width=1.5),
                **_axes(col),
            )
        )
    return out


def _bcls_marks(rows: Rows, key: str, col: int) -> list[dict[str, Any]]:
    """Open crosses on the BCLS mean where its known-noise model fails (no dither, overload)."""
    ok = _holds(rows, "bcls_holds")
    pts = [(r["bits"], get(r, key, "mean")) for r in rows if not ok[r["bits"]]]
    pts = [(b, y) for b, y in pts if y is not None and np.isfinite(y) and y > 0]
    if not pts:
        return []
    return [
        dict(
            type="scatter",
            x=[p[0] for p in pts],
            y=[p[1] for p in pts],
            mode="markers",
            name="BCLS: noise not ε²/12",
            legendgroup="bclsx",
            showlegend=(col == 1),
            marker=dict(color=COLORS["BCLS"], symbol="x-open", size=11),
            **_axes(col),
        )
    ]


def _theory_and_reference(
    rows: Rows, key: str, col: int, ref_slope: float, name: str = "Theorem 1"
) -> list[dict[str, Any]]:
    """Theorem 1's prediction (dashed / faded) and a ``ref_slope``/bit line through the first mean (dotted)."""
    out = _theorem1(rows, key, col, name=name)
    mx, my = xy(rows, key, "mean")
    if mx:
        b = np.array([mx[0], max(mx[-1], mx[0] + 1)])
        ry = my[0] * 10.0 ** (ref_slope * (b - mx[0]))
        out.append(
            dict(
                type="scatter",
                x=b.tolist(),
                y=ry.tolist(),
                mode="lines",
                name=f"{ref_slope:+.3f}/bit",
                legendgroup="ref",
                showlegend=(col == 1),
                line=dict(color=COLORS["ref"], dash="dot"),
                **_axes(col),
            )
        )
    return out


#: Two panels side by side (as ``make_subplots(1, 2, horizontal_spacing=0.12)`` lays them out).
_PANELS = (("‖A−Â‖/‖A‖", [0.0, 0.44]), ("‖B−B̂‖/‖B‖", [0.56, 1.0]))
#: The slopes the letter reads off its Fig. 1 (log10 error per bit) for A and for B.
LETTER_SLOPES = (-0.301, -0.322)
#: The system those slopes are the letter's for (its Fig. 1).
LETTER_SYSTEM = "dc-motor"


def slope_text(rows: Rows, key: str, letter: float | None) -> str:
    """'slope −0.30/bit (letter −0.301)': the fitted log10 slope of the mean over the rows' b ('' if < 3 b);
    without ``letter`` (a system the letter reads no slope off) just 'slope −0.30/bit'."""
    bx, by = xy(rows, key, "mean")
    if len(bx) < 3:
        return ""
    s = fit_slope(bx, by)
    return (f"slope {s:+.2f}/bit" + (f" (letter {letter:+.3f})" if letter is not None else "")).replace("-", "−")


def _theory_values(rows: Rows) -> tuple[tuple[int, float | None, float | None], ...]:
    """The series' Theorem 1 predictions (b, A, B), to tell series with the same prediction apart."""
    return tuple(
        (r["bits"], r.get("err_A_theory"), r.get("err_B_theory")) for r in sorted(rows, key=lambda r: r["bits"])
    )


def error_figure(
    series: Series,
    current_bits: int | None = None,
    ref_slope: float = -0.301,
    height: int = 330,
    theory_per_series: bool = False,
    bcls: Iterable[str] | None = None,
    letter_slopes: tuple[float, float] | None = LETTER_SLOPES,
) -> go.Figure:
    """Relative errors of A^ and B^ against b (two panels, log y).

    Each series draws mean +- std over realizations; the Theorem 1 prediction
    (taken from the first series) is dashed; a grey dotted line of slope
    ``ref_slope`` per bit (the letter's -0.301 = -log10 2) passes through the
    first series' mean at the smallest b; the current b is marked.
    With ``theory_per_series`` every later series whose Theorem 1 prediction
    differs (another system, data length, word length per channel, dither kind)
    also gets its own dashed line in the series' colour (equal predictions are
    drawn once); the first series' line keeps the theory colour.
    ``bcls`` names the series estimated by BCLS (default: the one labelled
    "BCLS"): open crosses mark the b where its known-noise model fails. ``letter_slopes``: the slopes the
    letter reads off for A and B (its DC motor's, the default), printed next to the fitted ones; None for a
    system the letter gives none for.
    """
    bcls = {"BCLS"} if bcls is None else set(bcls)
    data, lines, drawn = [], [], set()
    several = theory_per_series and len({_theory_values(rows) for rows in series.values()}) > 1
    for i, (label, rows) in enumerate(series.items()):
        th = _theory_values(rows)
        name = f"Theorem 1 · {label}" if several else "Theorem 1"
        for col, key in ((1, "err_A"), (2, "err_B")):
            data += band(rows, key, color(label, i), label, showlegend=(col == 1), **_axes(col))
            if i == 0:
                lines += _theory_and_reference(rows, key, col, ref_slope, name=name)
            elif several and th not in drawn:
                lines += _theorem1(rows, key, col, name=name, line_color=color(label, i))
            if label in bcls:
                data += _bcls_marks(rows, key, col)
        drawn.add(th)
    data += lines  # the theory and reference lines last: drawn above the data, never hidden by them
    first = next(iter(series.values()), [])
    notes = [f"Theorem 1 faded: {w}" for w in theorem1_reasons(first)]
    notes += [f"Theorem 1 kept: {w}" for w in fits_reasons(first)]
    for lab in [lab for lab in series if lab in bcls][:1]:
        notes += [f"BCLS ✕: {w}" for w in bcls_reasons(series[lab])]
    annotations = _panel_titles(first, letter_slopes)
    if notes:  # one readable line; the sentences on hover (and in the summary), never small print over the plot
        annotations.append(_notes_line(notes))
    layout: dict[str, Any] = dict(annotations=annotations, shapes=mark_bits(current_bits, (("x", "y"), ("x2", "y2"))))
    for col, (_, dom) in enumerate(_PANELS, start=1):
        ax = _axes(col)
        layout["xaxis" if col == 1 else f"xaxis{col}"] = dict(BITS_AXIS, anchor=ax["yaxis"], domain=dom)
        layout["yaxis" if col == 1 else f"yaxis{col}"] = dict(
            type="log", exponentformat="power", anchor=ax["xaxis"], domain=[0.0, 1.0]
        )
    top = 30 + (NOTE_FONT + 8 if notes else 0)
    return figure(
        data,
        dict(
            layout,
            height=height + top - 30,
            # the legend at the figure's foot, below the axis titles whatever its rows (never over them)
            margin=dict(l=50, r=10, t=top, b=100),
            legend=dict(orientation="h", yref="container", y=0, yanchor="bottom"),
        ),
    )


def _panel_titles(first: Rows, letter_slopes: tuple[float, float] | None) -> list[dict[str, Any]]:
    """Each panel's title with the first series' fitted slope beside it (and the letter's, if given)."""
    slopes = (slope_text(first, k, ls) for k, ls in zip(("err_A", "err_B"), letter_slopes or (None, None)))
    titles = [t + (f"<span style='font-size:12px'>  {s}</span>" if s else "") for (t, _), s in zip(_PANELS, slopes)]
    return [
        dict(
            text=t,
            x=sum(dom) / 2,
            xanchor="center",
            xref="paper",
            y=1.0,
            yanchor="bottom",
            yref="paper",
            showarrow=False,
            font=dict(size=16),
        )
        for t, (_, dom) in zip(titles, _PANELS)
    ]


#: Size (px) of the one-line note above the error plot.
NOTE_FONT = 12


def _notes_head(notes: list[str]) -> str:
    """'Theorem 1 faded · BCLS ✕': who the notes are about, once each, in order."""
    heads = [n.partition(": ")[0] for n in notes]
    return " · ".join(dict.fromkeys(heads))


def _notes_line(notes: list[str]) -> dict[str, Any]:
    """One line above the panels naming who the notes are about; the full sentences on hover."""
    return dict(
        text=f"Notes: {_notes_head(notes)} {HOVER_HERE}",
        hovertext="<br>".join(_wrap(t) for t in notes),
        xref="paper",
        yref="paper",
        x=0,
        y=1.0,
        yanchor="bottom",
        xanchor="left",
        yshift=24,
        showarrow=False,
        align="left",
        font=dict(size=NOTE_FONT, color="#555555"),
    )


def _wrap(text: str, width: int = 95) -> str:
    """Break a note into lines of at most ``width`` characters (plotly does not wrap)."""
    lines, cur = [], ""
    for w in text.split():
        if cur and len(cur) + 1 + len(w) > width:
            lines.append(cur)
            cur = w
        else:
            cur = f"{cur} {w}".strip()
    return "<br>".join(lines + [cur])


VIEW = View(
    "error",
    aspect=0.62,
    depends=CURVES,
    build=lambda frame: error_figure(
        frame.series(),
        current_bits=frame.bits,
        height=300,
        letter_slopes=LETTER_SLOPES if frame.system.name == LETTER_SYSTEM else None,
    ),
)


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


def lifted_error_figure(
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


def _lifted_build(frame: Any) -> go.Figure:
    return lifted_error_figure(frame.series(), frame.bits, bool(frame.values.guard))


#: The view of a nonlinear frame (its result holds a lifting).
LIFTED_VIEW = View("koopman-error", aspect=0.62, depends=CURVES, build=_lifted_build, tab="Nonlinear")
