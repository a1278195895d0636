"""View: the quantizer on one channel of the training data, with subtractive dither and without.

Top: a short window of the signal, its quantized values with subtractive dither
(``Q(x + w) - w``) and without (``Q(x)``). Middle: the two errors against the
signal value (plain: a deterministic sawtooth of x; dithered: a uniform band
whatever x is), with a one-line reading of how much of each error is fixed by x.
Bottom: histograms of the two errors (density) against the uniform density
``1/ε`` on ``±ε/2`` (alike with and without dither: the histogram cannot show
the difference, the middle panel does). The title gives the
measured error variance next to ``ε²/12`` and the overload fraction. The
numbers are :func:`qsid_core.quantization.quantizer_demo.channel_demo`'s; this module draws.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import plotly.graph_objects as go

from qsid_core import QuantizerDemo, channel_demo

from .palette import COLORS
from .raw import arr, figure, stacked_axes
from .view import CURRENT, FrameView, View

if TYPE_CHECKING:
    from qsid_core import LTISystem

__all__ = ["quantizer_figure", "demo_text", "dependence_text", "VIEW"]

#: Colours of the two quantizers (dithered = the BCLS/theory story, plain = grey).
DITHERED, PLAIN = COLORS["LS"], COLORS["ref"]


def demo_text(d: QuantizerDemo) -> str:
    """One line: ε, measured variances against ε²/12, overload (for the title and the summary).

    The ± is the sampling error of an ideal (uniform) error's variance: it is shown only without
    overload; with overload the errors outside ±ε/2 (not in the histogram) are counted instead.
    """
    ideal = d.outside_dithered == 0 and d.overload_dithered == 0
    spread = f" (± {d.var_sampling_std / d.var_theory:.3f})" if ideal else ""
    text = (
        f"{d.label}, b = {d.bits}: ε = {d.eps:.3g} · error variance / (ε²/12): dithered "
        f"{d.var_dithered / d.var_theory:.3g}{spread}, plain {d.var_plain / d.var_theory:.3g} · "
        f"overload {100 * d.overload_dithered:.2f} %"
    )
    if d.outside_dithered > 0 or d.outside_plain > 0:
        text += (
            f"<br>errors outside ±ε/2 (off the histogram): dithered {100 * d.outside_dithered:.2f} %, "
            f"plain {100 * d.outside_plain:.2f} % — the ε²/12 law needs no overload"
        )
    return text


def dependence_text(d: QuantizerDemo) -> str:
    """One-line reading of the error-vs-signal panel: how much of each error the signal value fixes."""
    return (
        f"error fixed by x's place in its cell: plain {100 * d.cell_dependence_plain:.0f} % (a sawtooth of x), "
        f"dithered {100 * d.cell_dependence_dithered:.1f} % (independent of x)<br>correlation with x: plain "
        f"{d.corr_plain:+.2f}, dithered {d.corr_dithered:+.2f} (it misses the sawtooth at fine b)"
    )


def quantizer_figure(d: QuantizerDemo, height: int = 640) -> go.Figure:
    """Signal window (top); errors against the signal value (middle); error histograms vs uniform (bottom)."""
    layout, (y1, y2, y3) = stacked_axes(3, gap=0.21)  # room for the note above the middle panel
    layout["xaxis"] = dict(anchor=y1, title=dict(text="sample"))
    layout["xaxis2"] = dict(anchor=y2, title=dict(text=f"signal value {d.label}"))
    layout["xaxis3"] = dict(anchor=y3, title=dict(text="quantization error (signal units)"))
    layout["yaxis2"]["anchor"] = "x2"
    layout["yaxis3"]["anchor"] = "x3"
    layout["yaxis"]["title"] = dict(text=d.label or "signal", font=dict(size=10))
    layout["yaxis2"]["title"] = dict(text="error x − x̃", font=dict(size=10))
    layout["yaxis3"]["title"] = dict(text="density", font=dict(size=10))
    data = _signal_traces(d, y1) + _error_traces(d, y2) + _histogram_traces(d, y3)
    top2 = layout["yaxis2"]["domain"][1]
    note = dict(
        text=dependence_text(d),
        xref="paper",
        yref="paper",
        x=0,
        y=top2,
        xanchor="left",
        yanchor="bottom",
        showarrow=False,
        align="left",
        font=dict(size=10, color="#444444"),
    )
    layout.update(
        height=height,
        barmode="overlay",
        bargap=0,
        margin=dict(l=60, r=10, t=50, b=40),
        annotations=[note],
        title=dict(text=demo_text(d), font=dict(size=11)),
        legend=dict(orientation="h", y=-0.12),
    )
    return figure(data, layout)


def _signal_traces(d: QuantizerDemo, y1: str) -> list[dict[str, Any]]:
    """Top panel (axis ``y1``): the signal window, quantized with subtractive dither and without."""
    return [
        dict(
            type="scatter",
            x=arr(d.t),
            y=arr(d.signal),
            mode="lines",
            name="signal",
            xaxis="x",
            yaxis=y1,
            line=dict(color=COLORS["true"], width=1.5),
        ),
        dict(
            type="scatter",
            x=arr(d.t),
            y=arr(d.dithered),
            mode="lines",
            name="Q(x+w)−w (subtractive dither)",
            xaxis="x",
            yaxis=y1,
            line=dict(color=DITHERED, width=1),
        ),
        dict(
            type="scatter",
            x=arr(d.t),
            y=arr(d.plain),
            mode="lines",
            name="Q(x) (no dither)",
            xaxis="x",
            yaxis=y1,
            line=dict(color=PLAIN, width=1, shape="hv"),
        ),
    ]


def _error_traces(d: QuantizerDemo, y2: str) -> list[dict[str, Any]]:
    """Middle panel (axis ``y2``): the quantization error against the signal value, with and without dither."""
    data: list[dict[str, Any]] = []
    for name, e, c, sym in (
        ("error vs x, dithered", d.scatter_dithered, DITHERED, "circle"),
        ("error vs x, no dither", d.scatter_plain, PLAIN, "diamond"),
    ):
        data.append(
            dict(
                type="scatter",
                x=arr(d.scatter_x),
                y=arr(e),
                mode="markers",
                name=name,
                xaxis="x2",
                yaxis=y2,
                marker=dict(color=c, size=3, opacity=0.6, symbol=sym),
            )
        )
    return data


def _histogram_traces(d: QuantizerDemo, y3: str) -> list[dict[str, Any]]:
    """Bottom panel (axis ``y3``): histograms of both errors against the uniform density ``1/eps``."""
    data: list[dict[str, Any]] = []
    centers = 0.5 * (d.hist_edges[1:] + d.hist_edges[:-1])
    width = float(np.diff(d.hist_edges).mean())
    for name, h, c in (("error, dithered", d.hist_dithered, DITHERED), ("error, no dither", d.hist_plain, PLAIN)):
        data.append(
            dict(
                type="bar",
                x=arr(centers),
                y=arr(h),
                width=width,
                name=name,
                xaxis="x3",
                yaxis=y3,
                marker=dict(color=c),
                opacity=0.55,
            )
        )
    e2 = d.eps / 2
    data.append(
        dict(
            type="scatter",
            x=[-e2, -e2, e2, e2],
            y=[0, d.uniform_density, d.uniform_density, 0],
            mode="lines",
            name="uniform 1/ε on ±ε/2",
            xaxis="x3",
            yaxis=y3,
            line=dict(color=COLORS["theory"], dash="dash", width=2),
        )
    )
    return data


def channel_names(system: LTISystem) -> tuple[str, ...]:
    """The channels the view offers: states, then inputs (``channel_demo``'s numbering)."""
    return tuple(f"x: {s}" for s in system.state_names) + tuple(f"u: {u}" for u in system.input_names)


def _build(frame: FrameView) -> go.Figure:
    k = min(max(int(frame.values.view_channel), 0), frame.system.n + frame.system.m - 1)
    assert frame.ex is not None  # a frame the views draw holds its experiment
    d = channel_demo(frame.ex, k, frame.bits, window=120)
    d.label = channel_names(frame.system)[k]  # "x: angle" rather than the engine's "x1"
    return quantizer_figure(d)


def _key(frame: FrameView) -> tuple[int, int, int | None]:
    return (frame.bits, frame.values.view_channel, id(frame.ex.prepared) if frame.ex is not None else None)


VIEW = View("quantizer", aspect=1.0, depends=CURRENT, build=_build, tab="Quantizer", key=_key)
