"""View: the steady-state error of the closed loops against b, next to the true-model loop's.

The steady-state error is the RMS of ``||x_t - x_ref||`` over the last half of each
loop. With a disturbance or a quantized / noisy measurement in the loop
(:mod:`qsid_core.control.loop_noise`) the true-model loop keeps a residual too: that part
is the disturbance and the measurement alone, the rest is the model error (the
only cause the letter's delta covers). Without them it is what is left of the
transient after the drawn number of steps.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import plotly.graph_objects as go

from .hypotheses import bits_text
from .palette import COLORS, color
from .raw import figure, hline
from .traces import BITS_AXIS, Series, hline_note, mark_bits, xy
from .view import CURVES, FrameView, View

if TYPE_CHECKING:
    from qsid_core import MPCConfig

__all__ = ["residual_figure", "VIEW", "ROUNDOFF"]

#: A steady-state error below this times max(‖x0‖, 1) is round-off of a loop that settled exactly.
ROUNDOFF = 1e-10


def residual_figure(
    series: Series,
    true_error: float | None = None,
    current_bits: int | None = None,
    causes: str = "",
    height: int = 280,
    tracking: bool = False,
    true_tracking: float | None = None,
    exact_below: float = 0.0,
) -> go.Figure:
    """Mean and max steady-state error per estimator against b; the true-model loop's as a dashed line.

    With ``tracking`` (a time-varying reference) also the tracking error over the whole loop (dotted).
    Errors below ``exact_below`` are numerical round-off of a loop that reached its target exactly: they are
    not drawn (a log axis would show 1e-14..1e-25 as if they meant something); the title says "exact" instead.
    """
    data, shapes, notes = [], mark_bits(current_bits), []
    exact: set = set()

    def real(bx: list, by: list) -> tuple[list, list]:  # the points above round-off; the b of the others are "exact"
        keep = [(b, y) for b, y in zip(bx, by) if not (y is not None and np.isfinite(y) and y < exact_below)]
        exact.update(b for b, y in zip(bx, by) if y is not None and np.isfinite(y) and y < exact_below)
        return [b for b, _ in keep], [y for _, y in keep]

    for i, (label, rows) in enumerate(series.items()):
        c = color(label, i)
        bx, by = real(*xy(rows, "steady_state_error", "mean"))
        data.append(dict(type="scatter", x=bx, y=by, mode="lines+markers", name=f"{label} mean", line=dict(color=c)))
        mx, my = real(*xy(rows, "steady_state_error", "max"))
        data.append(
            dict(
                type="scatter",
                x=mx,
                y=my,
                mode="markers",
                name=f"{label} max",
                marker=dict(color=c, symbol="triangle-up"),
            )
        )
        if tracking:
            tx, ty = real(*xy(rows, "tracking_error", "mean"))
            data.append(
                dict(
                    type="scatter",
                    x=tx,
                    y=ty,
                    mode="lines+markers",
                    name=f"{label} tracking (whole loop)",
                    line=dict(color=c, dash="dot"),
                    marker=dict(symbol="square", size=5),
                )
            )
    exact_true = []
    for val, what, dash in ((true_error, "true model", "dash"), (true_tracking, "true model, tracking", "dot")):
        if val is not None and np.isfinite(val) and val < exact_below:
            exact_true.append(what)
        elif val is not None and np.isfinite(val) and val > 0:
            shapes.append(hline(float(val), "y", COLORS["true"], dash, 2.0))
            notes.append(hline_note(val, f"{what} {val:.3g}", where="bottom" if dash == "dot" else "top"))
    title = "steady-state error (RMS of ‖x_t − x_ref‖, last half of the loop)" + (
        f"<br>causes besides the model: {causes}"
        if causes
        else "<br>exact state, no disturbance: what is left of the transient"
    )
    if exact or exact_true:
        who = ", ".join(exact_true + ([bits_text(sorted(exact))] if exact else []))
        title += f"<br>exact (0 up to round-off, not drawn): {who}"
    return figure(
        data,
        dict(
            height=height,
            margin=dict(l=50, r=10, t=30 + 14 * title.count("<br>"), b=40),
            legend=dict(orientation="h", y=-0.3),
            title=dict(text=title, font=dict(size=11), x=0, xanchor="left", xref="paper"),
            shapes=shapes,
            annotations=notes,
            xaxis=dict(BITS_AXIS),
            yaxis=dict(type="log", title=dict(text="steady-state error"), exponentformat="power"),
        ),
    )


def causes_text(mpc: MPCConfig | None) -> str:
    """The loop's residual causes in words ('' for a clean loop)."""
    if mpc is None:
        return ""
    out = []
    if mpc.disturbance:
        out.append(f"disturbance σ {mpc.disturbance:g} ({mpc.disturbance_kind})")
    if mpc.feedback_bits is not None:
        out.append(f"feedback quantized to {mpc.feedback_bits} bits per state")
    if mpc.feedback_noise:
        out.append(f"sensor noise σ {mpc.feedback_noise:g}")
    if mpc.reference is not None:
        out.append("a time-varying reference")
    return ", ".join(out)


def _build(frame: FrameView) -> go.Figure:
    tl = frame.true_loop
    true_err = float(tl.steady_state_error[0]) if tl is not None else None
    mpc = frame.ex.config.mpc if frame.ex is not None else None
    tracking = mpc is not None and mpc.reference is not None
    true_tr = float(tl.tracking_error[0]) if (tl is not None and tracking) else None
    scale = max(float(np.linalg.norm(frame.x0)), 1.0) if frame.x0 is not None else 1.0
    return residual_figure(
        frame.series(),
        true_err,
        frame.bits,
        causes_text(mpc),
        tracking=tracking,
        true_tracking=true_tr,
        exact_below=ROUNDOFF * scale,
    )


VIEW = View("residual", aspect=0.6, depends=CURVES, build=_build, tab="Control")
