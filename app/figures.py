"""Plotly figure builders shared by the ``qsid`` command line and the dashboard.

They draw what the engine computed; the only arithmetic here is reshaping for
display (mean +- std bands, a reference line through a chosen point).

Inputs are plain data: *rows* are the JSON-ready per-b summaries of
:func:`qsid_core.sweep.summary_row` (the ``results`` entries of
``qsid sweep --json``); a *series* maps a label (``"LS"``, ``"BCLS"``) to a list
of rows. Missing values (``None``) are skipped, so partially filled sweeps draw.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import plotly.graph_objects as go
from plotly.subplots import make_subplots

__all__ = [
    "COLORS",
    "error_figure",
    "cost_figure",
    "bound_figure",
    "eigen_figure",
    "phase_portrait_figure",
]

COLORS = {"LS": "#1f77b4", "BCLS": "#d62728", "theory": "#2ca02c", "ref": "#7f7f7f", "true": "#000000"}
_PALETTE = ["#1f77b4", "#d62728", "#9467bd", "#ff7f0e"]

Rows = Sequence[Mapping]
Series = Mapping[str, Rows]


def _color(label: str, i: int) -> str:
    return COLORS.get(label, _PALETTE[i % len(_PALETTE)])


def _get(row: Mapping, *path):
    v = row
    for p in path:
        if v is None:
            return None
        v = v.get(p) if isinstance(v, Mapping) else None
    return v


def _xy(rows: Rows, *path) -> tuple[list, list]:
    xs, ys = [], []
    for r in sorted(rows, key=lambda r: r["bits"]):
        v = _get(r, *path)
        if v is not None and np.isfinite(v) and v > 0:
            xs.append(r["bits"])
            ys.append(float(v))
    return xs, ys


def _band(fig, rows: Rows, key: str, color: str, name: str, row=None, col=None, showlegend=True) -> None:
    """Mean line with a mean +- std band (clipped above zero for the log axis)."""
    pts = []
    for r in sorted(rows, key=lambda r: r["bits"]):
        m, s = _get(r, key, "mean"), _get(r, key, "std")
        if m is not None and np.isfinite(m) and m > 0:
            pts.append((r["bits"], m, s or 0.0))
    if not pts:
        return
    b = [p[0] for p in pts]
    m = np.array([p[1] for p in pts])
    s = np.array([p[2] for p in pts])
    up = m + s
    lo = np.where(m - s > 0, m - s, m / 10)
    kw = {} if row is None else {"row": row, "col": col}
    fig.add_trace(go.Scatter(x=b + b[::-1], y=list(up) + list(lo[::-1]), fill="toself", fillcolor=color,
                             opacity=0.18, line=dict(width=0), hoverinfo="skip", showlegend=False,
                             legendgroup=name), **kw)
    fig.add_trace(go.Scatter(x=b, y=list(m), mode="lines+markers", name=name, legendgroup=name,
                             showlegend=showlegend, line=dict(color=color),
                             error_y=dict(type="data", array=list(s), visible=False)), **kw)


def _mark_bits(fig, current_bits: int | None, **kw) -> None:
    if current_bits is not None:
        fig.add_vline(x=current_bits, line=dict(color="#444", dash="dot", width=1), **kw)


def error_figure(series: Series, current_bits: int | None = None, ref_slope: float = -0.301,
                 height: int = 330) -> go.Figure:
    """Relative errors of A^ and B^ against b (two panels, log y).

    Each series draws mean +- std over realizations; the Theorem 1 prediction
    (taken from the first series) is dashed; a grey dotted line of slope
    ``ref_slope`` per bit (the letter's -0.301 = -log10 2) passes through the
    first series' mean at the smallest b; the current b is marked.
    """
    fig = make_subplots(rows=1, cols=2, subplot_titles=("‖A−Â‖/‖A‖", "‖B−B̂‖/‖B‖"), horizontal_spacing=0.12)
    first = True
    for i, (label, rows) in enumerate(series.items()):
        c = _color(label, i)
        for col, key in ((1, "err_A"), (2, "err_B")):
            _band(fig, rows, key, c, label, row=1, col=col, showlegend=(col == 1))
            if first:
                tx, ty = _xy(rows, f"{key}_theory")
                if tx:
                    fig.add_trace(go.Scatter(x=tx, y=ty, mode="lines", name="Theorem 1", legendgroup="th",
                                             showlegend=(col == 1), line=dict(color=COLORS["theory"], dash="dash")),
                                  row=1, col=col)
                mx, my = _xy(rows, key, "mean")
                if mx:
                    b = np.array([mx[0], max(mx[-1], mx[0] + 1)])
                    ry = my[0] * 10.0 ** (ref_slope * (b - mx[0]))
                    fig.add_trace(go.Scatter(x=b.tolist(), y=ry.tolist(), mode="lines",
                                             name=f"{ref_slope:+.3f}/bit", legendgroup="ref", showlegend=(col == 1),
                                             line=dict(color=COLORS["ref"], dash="dot")), row=1, col=col)
        first = False
    fig.update_yaxes(type="log", exponentformat="power")
    fig.update_xaxes(title_text="word length b [bits]", dtick=2)
    _mark_bits(fig, current_bits, row="all", col="all")
    fig.update_layout(height=height, margin=dict(l=50, r=10, t=30, b=40), legend=dict(orientation="h", y=-0.25),
                      template="plotly_white")
    return fig


def cost_figure(series: Series, true_cost: float | None = None, current_bits: int | None = None,
                height: int = 300) -> go.Figure:
    """Realised closed-loop MPC cost on the true system against b, vs the true-model cost."""
    fig = go.Figure()
    for i, (label, rows) in enumerate(series.items()):
        _band(fig, rows, "mpc_cost", _color(label, i), f"{label} model")
    if true_cost is not None and np.isfinite(true_cost):
        fig.add_hline(y=true_cost, line=dict(color=COLORS["true"], dash="dash"),
                      annotation_text=f"true model {true_cost:.4g}", annotation_position="top right")
    _mark_bits(fig, current_bits)
    fig.update_yaxes(type="log", title_text="closed-loop cost")
    fig.update_xaxes(title_text="word length b [bits]", dtick=2)
    fig.update_layout(height=height, margin=dict(l=50, r=10, t=20, b=40), template="plotly_white",
                      legend=dict(orientation="h", y=-0.3))
    return fig


def bound_figure(series: Series, current_bits: int | None = None, height: int = 300) -> go.Figure:
    """Ultimate bound delta(eps) (theory) against the measured final state norm (mean and max)."""
    fig = go.Figure()
    for i, (label, rows) in enumerate(series.items()):
        c = _color(label, i)
        if i == 0:
            bx, by = _xy(rows, "ultimate_bound")
            fig.add_trace(go.Scatter(x=bx, y=by, mode="lines+markers", name="δ(ε) bound",
                                     line=dict(color=COLORS["theory"], dash="dash")))
        mx, my = _xy(rows, "final_state_norm", "mean")
        fig.add_trace(go.Scatter(x=mx, y=my, mode="lines+markers", name=f"{label} ‖x_T‖ mean", line=dict(color=c)))
        xx, xy = _xy(rows, "final_state_norm", "max")
        fig.add_trace(go.Scatter(x=xx, y=xy, mode="markers", name=f"{label} ‖x_T‖ max",
                                 marker=dict(color=c, symbol="triangle-up")))
    _mark_bits(fig, current_bits)
    fig.update_yaxes(type="log", title_text="norm", exponentformat="power")
    fig.update_xaxes(title_text="word length b [bits]", dtick=2)
    fig.update_layout(height=height, margin=dict(l=50, r=10, t=20, b=40), template="plotly_white",
                      legend=dict(orientation="h", y=-0.3))
    return fig


def eigen_figure(eigs: Mapping[str, np.ndarray] | np.ndarray, true_eigs: np.ndarray, height: int = 320,
                 title: str = "") -> go.Figure:
    """Eigenvalues of the identified A^ over realizations, the true ones, and the unit circle.

    ``eigs`` is an array of shape (R, n) (complex) or a mapping label -> such arrays.
    """
    if not isinstance(eigs, Mapping):
        eigs = {"Â": eigs}
    th = np.linspace(0, 2 * np.pi, 181)
    fig = go.Figure(go.Scatter(x=np.cos(th), y=np.sin(th), mode="lines", name="unit circle",
                               line=dict(color="#bbb", width=1), hoverinfo="skip"))
    for i, (label, ev) in enumerate(eigs.items()):
        ev = np.asarray(ev).reshape(-1)
        fig.add_trace(go.Scatter(x=ev.real, y=ev.imag, mode="markers", name=f"eig {label}",
                                 marker=dict(color=_color(label, i), size=6, opacity=0.5)))
    te = np.asarray(true_eigs).reshape(-1)
    fig.add_trace(go.Scatter(x=te.real, y=te.imag, mode="markers", name="eig A (true)",
                             marker=dict(color=COLORS["true"], symbol="x", size=11)))
    fig.update_xaxes(title_text="Re", zeroline=True)
    fig.update_yaxes(title_text="Im", scaleanchor="x", scaleratio=1, zeroline=True)
    fig.update_layout(height=height, margin=dict(l=50, r=10, t=30 if title else 10, b=40), template="plotly_white",
                      title=title or None, legend=dict(orientation="h", y=-0.25))
    return fig


def phase_portrait_figure(states: np.ndarray, true_states: np.ndarray | None = None, dims=(0, 1, 2),
                          names: Sequence[str] | None = None, title: str = "", height: int = 520) -> go.Figure:
    """3-D phase portrait: one line per realization (R, T+1, n) plus the true-model trajectory.

    ``dims`` picks the three states drawn (for 4-state systems).
    """
    states = np.asarray(states, dtype=float)
    names = list(names) if names is not None else [f"x{i + 1}" for i in range(states.shape[-1])]
    i, j, k = dims
    xs, ys, zs = [], [], []
    for tr in states:
        ok = np.all(np.isfinite(tr[:, [i, j, k]]), axis=1)
        if not ok.any():
            continue
        xs += tr[ok, i].tolist() + [None]
        ys += tr[ok, j].tolist() + [None]
        zs += tr[ok, k].tolist() + [None]
    fig = go.Figure(go.Scatter3d(x=xs, y=ys, z=zs, mode="lines", name=f"{states.shape[0]} realizations",
                                 line=dict(color="#1f77b4", width=2), opacity=0.6))
    if true_states is not None:
        ts = np.asarray(true_states, dtype=float)
        fig.add_trace(go.Scatter3d(x=ts[:, i], y=ts[:, j], z=ts[:, k], mode="lines", name="true model",
                                   line=dict(color="#d62728", width=5)))
        fig.add_trace(go.Scatter3d(x=[ts[0, i]], y=[ts[0, j]], z=[ts[0, k]], mode="markers", name="x0",
                                   marker=dict(color="#000", size=5)))
    fig.update_layout(
        title=title or None, height=height, margin=dict(l=0, r=0, t=40 if title else 10, b=0),
        scene=dict(xaxis_title=names[i], yaxis_title=names[j], zaxis_title=names[k]),
        legend=dict(orientation="h", y=0.02),
    )
    return fig


def move_current_bits(fig: go.Figure, current_bits: int) -> go.Figure:
    """Move the dotted current-b marker(s) drawn by the builders above to ``current_bits``, in place.

    A cheap redraw for the dashboard when only b changed (the curves stay). Figures
    built without ``current_bits`` have no marker and are returned unchanged.
    """
    for shape in fig.layout.shapes:
        if shape.x0 == shape.x1 and str(shape.yref or "").endswith("domain"):
            shape.x0 = shape.x1 = current_bits
    return fig
