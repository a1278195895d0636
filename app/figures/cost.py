"""View: realised closed-loop MPC cost on the true system against b (the letter's panel (c))."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import plotly.graph_objects as go

from .palette import COLORS, color
from .raw import figure, hline
from .traces import BITS_AXIS, Series, band, hline_note, mark_bits
from .view import CURVES, View

__all__ = ["cost_figure", "VIEW"]


def cost_figure(
    series: Series,
    true_cost: float | None = None,
    current_bits: int | None = None,
    height: int = 300,
    more_true: Sequence[tuple[str, float | None]] = (),
) -> go.Figure:
    """Mean +- std of the closed-loop cost per estimator against b, and the true-model cost (dashed).

    ``more_true`` adds further true-model costs as ``(label, cost)`` (results of other plants or
    MPC settings on one figure): each a dashed line in its series' colour, labelled.
    """
    data, shapes, notes = [], mark_bits(current_bits), []
    stuck = []
    for i, (label, rows) in enumerate(series.items()):
        data += band(rows, "mpc_cost", color(label, i), f"{label} model")
        bad = [
            (r["bits"], r["closed_loop_outcomes"])
            for r in rows
            if r.get("closed_loop_outcomes")
            and r["closed_loop_outcomes"]["converged"] < sum(r["closed_loop_outcomes"].values())
        ]
        if bad:
            stuck.append(
                f"{label}: " + ", ".join(f"b={b} {sum(o.values()) - o['converged']}/{sum(o.values())}" for b, o in bad)
            )
    if stuck:  # the cost of a loop that never settles is no success
        notes.append(
            dict(
                text="did not converge: " + "; ".join(stuck),
                showarrow=False,
                x=0,
                y=1.0,
                xref="paper",
                yref="paper",
                xanchor="left",
                yanchor="bottom",
                font=dict(size=10, color=COLORS["ref"]),
            )
        )
    if true_cost is not None and np.isfinite(true_cost) and true_cost > 0:
        shapes.append(hline(float(true_cost), "y", COLORS["true"], "dash", 2.0))
        notes.append(hline_note(true_cost, f"true model {true_cost:.4g}"))
    order = list(series)
    for label, c in more_true:
        if c is not None and np.isfinite(c) and c > 0 and c != true_cost:
            i = order.index(label) if label in order else len(order)
            shapes.append(hline(float(c), "y", color(label, i), "dash", 1.5))
            notes.append(hline_note(c, f"true model ({label}) {c:.4g}", x=0.5, size=9))
    return figure(
        data,
        dict(
            height=height,
            margin=dict(l=50, r=10, t=20, b=40),
            legend=dict(orientation="h", y=-0.3),
            shapes=shapes,
            annotations=notes,
            xaxis=dict(BITS_AXIS),
            yaxis=dict(type="log", title=dict(text="closed-loop cost"), exponentformat="power"),
        ),
    )


VIEW = View(
    "cost",
    aspect=0.6,
    depends=CURVES,
    build=lambda frame: cost_figure(frame.series(), true_cost=frame.true_cost, current_bits=frame.bits, height=260),
)
