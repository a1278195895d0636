"""View (offered when the result holds a lifting: a nonlinear plant): the Koopman MPC's outcomes on the true plant per word length, per estimator: the
shares of loops that converged (settled at the origin), stayed bounded (within the convergence radius at the end, or
beyond it), diverged or failed (observed, not certified)."""

from __future__ import annotations

from typing import Any

import plotly.graph_objects as go

from .raw import figure
from .traces import mark_bits
from .view import CURVES, View

__all__ = ["VIEW", "OUTCOME_COLORS", "SEGMENTS", "outcomes_figure"]

#: Colour of each outcome (converged green, bounded amber, diverged red, failed grey).
OUTCOME_COLORS = {"converged": "#2ca02c", "bounded": "#ffbf00", "diverged": "#d62728", "failed": "#7f7f7f"}
#: The bars' segments: the outcomes, the bounded loops split by whether they end within the convergence radius.
SEGMENTS = {
    "converged": OUTCOME_COLORS["converged"],
    "bounded, within radius": "#a6d96a",
    "bounded": OUTCOME_COLORS["bounded"],
    "diverged": OUTCOME_COLORS["diverged"],
    "failed": OUTCOME_COLORS["failed"],
}


def _counts(r: dict[str, Any]) -> dict[str, int]:
    """A row's loops per segment (a row without ``within_radius`` has no "bounded, within radius" part)."""
    oc = dict(r["closed_loop_outcomes"])
    near = max(0, min(oc["bounded"], int(r.get("within_radius") or 0) - oc["converged"]))
    return {**oc, "bounded, within radius": near, "bounded": oc["bounded"] - near}


def outcomes_figure(rows: dict[str, list[dict[str, Any]]], bits: int | None, height: int = 300) -> go.Figure:
    """Stacked shares per b, one bar per estimator label side by side (LS left, BCLS right)."""
    data: list[dict[str, Any]] = []
    labels = list(rows)
    width = 0.8 / max(len(labels), 1)
    for i, lab in enumerate(labels):
        done = [r for r in rows[lab] if r.get("closed_loop_outcomes")]
        xs = [r["bits"] - 0.4 + width * (i + 0.5) for r in done]
        counts = [_counts(r) for r in done]
        for k, col in SEGMENTS.items():
            ys = [c[k] / max(r["realizations"], 1) for c, r in zip(counts, done)]
            data.append(
                dict(
                    type="bar",
                    x=xs,
                    y=ys,
                    width=width * 0.92,
                    name=k,
                    legendgroup=k,
                    showlegend=i == 0,
                    marker=dict(color=col, line=dict(width=0)),
                    hovertemplate=f"{lab} %{{y:.0%}} {k}<extra></extra>",
                )
            )
    note = (
        " · ".join(f"{lab} {'left' if i == 0 else 'right'}" for i, lab in enumerate(labels))
        if len(labels) > 1
        else labels[0]
        if labels
        else ""
    )
    return figure(
        data,
        dict(
            height=height,
            barmode="stack",
            margin=dict(l=60, r=10, t=30, b=40),
            legend=dict(orientation="h", y=-0.25),
            xaxis=dict(title=dict(text="word length b (bits)"), dtick=2),
            yaxis=dict(title=dict(text="share of loops"), range=[0, 1], tickformat=".0%"),
            shapes=mark_bits(bits),
            title=dict(text=f"Koopman MPC on the true plant ({note})", font=dict(size=13)),
        ),
    )


def _build(frame: Any) -> go.Figure:
    return outcomes_figure(frame.series(), frame.bits)


VIEW = View("koopman-outcomes", aspect=0.55, depends=CURVES, build=_build, tab="Nonlinear")
