"""View: how many bits does the MPC need? Stabilized share and cost gap against b, with the three answers.

Top: the share of closed loops that converge on the true plant, per estimator,
with its 95 % Wilson interval, and the target. Bottom: the gap of the mean
closed-loop cost to the true-model MPC over the loops that did not diverge (log
scale, absolute value; the hover gives its sign) and the allowed gap. Vertical lines: ``b_observed`` (solid), ``b_robust`` (dashed, the
small-gain certificate for Theorem 1's predicted model) and ``b_letter``
(dotted, the letter's bound below rho and below ||x0||); the sentence of
:class:`qsid_core.studies.bits_answer.BitsAnswer` is the title.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import plotly.graph_objects as go

from qsid_core.control import data_rate_bits
from qsid_core.studies import BitsAnswer, answer_from_rows, certified_own_models_at, predicted_small_gains

from .palette import COLORS, color
from .raw import figure, hline, stacked_axes
from .traces import BITS_AXIS, Series, mark_bits
from .view import CURVES, FrameView, View

if TYPE_CHECKING:
    from qsid_core import Experiment

__all__ = ["bits_figure", "answers", "VIEW"]

#: line style of each answer's vertical marker
DASH = {"b_observed": "solid", "b_robust": "dash", "b_letter": "dot"}


def bits_figure(
    answers: dict[str, BitsAnswer], current_bits: int | None = None, height: int = 420, partial: str = ""
) -> go.Figure:
    """The figure of ``{label: BitsAnswer}`` (the first answer's three word lengths are marked)."""
    lay, (y1, y2) = stacked_axes(2, gap=0.08, x_title=BITS_AXIS["title"]["text"])
    data, shapes, notes = [], mark_bits(current_bits, (("x", y1), ("x", y2))), []
    first: BitsAnswer | None = None
    for i, (lab, ans) in enumerate(answers.items()):
        first = first or ans
        c = color(lab, i)
        data += _answer_traces(lab, ans, c, y1, y2)
    if first is not None:
        marks, labels = _target_marks(first, y1, y2)
        shapes += marks
        notes += labels
        # the target is named in the legend (a line of its own there): a label on the line collided with the
        # marks and the title on small or crowded plots
        t = first.settings["target"]
        data.append(
            dict(
                type="scatter",
                x=[None],
                y=[None],
                mode="lines",
                name=f"target {100 * t:g} %",
                line=dict(color=COLORS["ref"], dash="dash", width=1),
                yaxis=y1,
                hoverinfo="skip",
            )
        )
    title = "<br>".join(_wrap(f"{lab}: {a.sentence}") for lab, a in answers.items()) + partial
    lay[y1.replace("y", "yaxis")] = {
        **lay[y1.replace("y", "yaxis")],
        "title": dict(text="stabilized [%]"),
        "range": [-3, 103],
        "exponentformat": "none",
    }
    lay["yaxis2"] = {
        **lay["yaxis2"],
        "title": dict(text="|cost gap| [%]"),
        "type": "log",
        "exponentformat": "power",  # percent in powers of ten (10⁻⁶), never SI prefixes ("1μ" %)
    }
    return figure(
        data,
        dict(
            height=height,
            margin=dict(l=55, r=10, t=30 + 15 * title.count("<br>") + 14, b=40),
            # anchored at the top: a title of several lines grows down into the margin, not over the plot
            title=dict(
                text=title, font=dict(size=11), x=0, xanchor="left", yref="container", y=1, yanchor="top", pad=dict(t=8)
            ),
            legend=dict(orientation="h", y=-0.18),
            shapes=shapes,
            annotations=notes,
            xaxis={**lay.pop("xaxis"), **{k: v for k, v in BITS_AXIS.items() if k != "title"}},
            **lay,
        ),
    )


def _answer_traces(lab: str, ans: BitsAnswer, c: str, y1: str, y2: str) -> list[dict]:
    """One answer's traces: the stabilized fraction with its interval (axis ``y1``), the cost gap (``y2``)."""
    data: list[dict] = []
    rows = [r for r in ans.rows if r.stabilized_fraction is not None]
    b = [r.bits for r in rows]
    f = np.array([100 * r.stabilized_fraction for r in rows])
    lo = np.array([100 * r.interval[0] for r in rows])
    hi = np.array([100 * r.interval[1] for r in rows])
    data.append(
        dict(
            type="scatter",
            x=b,
            y=f.tolist(),
            mode="lines+markers",
            name=f"{lab} stabilized",
            legendgroup=lab,
            line=dict(color=c),
            yaxis=y1,
            error_y=dict(
                type="data",
                symmetric=False,
                array=(hi - f).tolist(),
                arrayminus=(f - lo).tolist(),
                color=c,
                thickness=1,
            ),
            hovertemplate="b = %{x}: %{y:.0f} % converged<extra>" + lab + "</extra>",
        )
    )
    gap = [(r.bits, abs(r.cost_gap), r.cost_gap) for r in rows if r.cost_gap is not None and abs(r.cost_gap) > 0]
    if gap:
        data.append(
            dict(
                type="scatter",
                x=[g[0] for g in gap],
                y=[100 * g[1] for g in gap],
                mode="lines+markers",
                name=f"{lab} cost gap",
                legendgroup=lab,
                showlegend=False,
                line=dict(color=c, dash="dash"),
                yaxis=y2,
                customdata=[f"{100 * g[2]:+.3g} %" for g in gap],
                hovertemplate="b = %{x}: gap %{customdata} (over the loops that did not diverge)<extra>"
                + lab
                + "</extra>",
            )
        )
    return data


def _target_marks(first: BitsAnswer, y1: str, y2: str) -> tuple[list[dict], list[dict]]:
    """``(shapes, annotations)``: the targets and the first answer's word lengths, marked on both axes."""
    shapes: list[dict] = []
    notes: list[dict] = []
    t, g = first.settings["target"], first.settings["cost_gap"]
    shapes.append(hline(100 * t, y1, COLORS["ref"], "dash"))
    if g > 0:
        shapes.append(hline(100 * g, y2, COLORS["ref"], "dash"))
    at: dict = {}  # b -> the answers marked there (one label, not several on top of each other)
    for key, dash in DASH.items():
        bk = getattr(first, key)
        if bk is None:
            continue
        at.setdefault(bk, []).append(key.replace("b_", ""))
        for ya in (y1, y2):
            shapes.append(
                dict(
                    type="line",
                    x0=bk,
                    x1=bk,
                    xref="x",
                    y0=0,
                    y1=1,
                    yref=f"{ya} domain",
                    line=dict(color=COLORS["theory"], dash=dash, width=2),
                )
            )
    for bk, names in at.items():
        notes.append(
            dict(
                text=", ".join(names) + f" {bk}",
                x=bk,
                xref="x",
                y=1,
                yref=f"{y1} domain",
                showarrow=False,
                xanchor="left",
                yanchor="top",
                textangle=-90,
                font=dict(size=10, color=COLORS["theory"]),
            )
        )
    return shapes, notes


def _wrap(text: str, width: int = 95) -> str:
    """``text`` broken at spaces into lines of about ``width`` characters (plotly's ``<br>``)."""
    out, line = [], ""
    for w in text.split(" "):
        if line and len(line) + 1 + len(w) > width:
            out.append(line)
            line = w
        else:
            line = f"{line} {w}" if line else w
    return "<br>".join(out + [line])


def answers(
    series: Series, true_cost: float | None, ex: Experiment, target: float, cost_gap: float
) -> dict[str, BitsAnswer]:
    """``{label: BitsAnswer}`` from the rows computed so far (the small-gain tests from ``ex``: Theorem 1's
    model, and each loop's own model where the loops are in ``ex``'s cache)."""
    out: dict[str, BitsAnswer] = {}
    robust: dict[int, Any] | None = None
    for lab, rows in series.items():
        rows = [r for r in rows if r.get("closed_loop_outcomes")]
        if not rows:
            continue
        if robust is None and ex is not None:
            robust = predicted_small_gains(ex, [int(r["bits"]) for r in rows])
        out[lab] = answer_from_rows(
            getattr(ex.system, "name", ""),
            {},
            rows,
            true_cost,
            robust=robust,
            robust_realized=_own_error(ex, lab.lower(), [int(r["bits"]) for r in rows]),
            target=target,
            cost_gap=cost_gap,
            data_rate=data_rate_bits(ex.system.A),
        )
    return out


def _own_error(ex: Experiment, estimator: str, bits: list[int]) -> dict[int, int] | None:
    """Per b, the loops the small-gain test certifies with their own model (None: not the engine's estimator)."""
    if ex is None or ex.config.mpc is None or estimator not in ("ls", "bcls"):
        return None
    return certified_own_models_at(ex, bits, estimator)


def _build(frame: FrameView) -> go.Figure:
    v = frame.values
    assert frame.ex is not None  # a frame the views draw holds its experiment
    ans = answers(frame.series(), frame.true_cost, frame.ex, float(v.target), float(v.cost_gap))
    partial = "" if frame.done >= frame.total else f"<br><i>(so far {frame.done} of {frame.total} word lengths)</i>"
    return bits_figure(ans, current_bits=frame.bits, height=420, partial=partial)


VIEW = View("bits", aspect=0.9, depends=CURVES, build=_build, tab="Control")
