"""What one tab redraws for a nonlinear frame (:class:`~app.dashboard.frames.KoopmanFrame`): the views of
:data:`app.figures.registry.KOOPMAN_VIEWS`, the 3-D scene of the plant's flow and loops, and the summary text.

The summary states what holds for a nonlinear plant: no linear certificate applies; BCLS's correction is exact
only for a polynomial dictionary with subtractive dither; the large-data limit only where its hypotheses hold.
"""

from __future__ import annotations

from typing import Any

from app.figures import registry
from app.figures.axes import finite_axes
from app.figures.koopman_error import limit_note
from app.figures.koopman_scene import koopman_scene
from app.figures.raw import Wire
from app.figures.traces import CURRENT_B, move_current_bits
from app.figures.view import CURRENT, CURVES
from qsid_core.studies import NO_CERTIFICATES

from .render import STYLES, Render, plot_aspect

__all__ = ["KoopmanRenderer", "koopman_figures", "koopman_summary", "bcls_exactness"]


def koopman_figures(frame: Any, which: Any = None) -> dict[str, Any]:
    """Plotly figures of the nonlinear views for ``frame`` (all, or the names in ``which``)."""
    return {v.name: finite_axes(v.build(frame)) for v in registry.KOOPMAN_VIEWS if which is None or v.name in which}


def bcls_exactness(values: Any) -> str:
    """One sentence: whether BCLS's de-biasing is exact for the panel's dictionary and dither."""
    lifting, dither = str(values.lifting).strip(), str(values.dither)
    if lifting.startswith("rbf"):
        return (
            f"BCLS: no exact correction for the radial functions of {lifting} (it falls back to LS); only "
            "polynomial dictionaries with subtractive dither are de-biased exactly."
        )
    if dither != "subtractive":
        return (
            f"BCLS: no exact correction with {dither} dither (the error is not independent uniform noise): the "
            "Bernoulli correction is applied nominally; it is exact only with subtractive dither."
        )
    return (
        f"BCLS: exact de-biasing of every monomial of {lifting} (polynomial dictionary, subtractive dither): the "
        "quantized moments' bias is removed, their spread is not."
    )


def _pm(s: dict[str, float] | None) -> str:
    if not s or s.get("mean") is None or s["mean"] != s["mean"]:
        return "–"
    return f"{s['mean']:.3g} ± {s['std']:.2g}"


def koopman_summary(frame: Any) -> str:
    """The summary text of a nonlinear frame (markdown)."""
    v, b = frame.values, frame.bits
    lines = [
        f"**{frame.system.name}** (nonlinear, Koopman/EDMD), dictionary `{str(v.lifting).strip()}` "
        f"({frame.features} features), {v.trajectories} × {v.steps} samples, {v.realizations} realizations.",
    ]
    parts = []
    for lab in frame.labels:
        r = frame.rows[lab].get(b, {})
        oc = r.get("closed_loop_outcomes")
        off = r.get("settled_offset")
        loops = (
            f", MPC converged {oc['converged']}/{r['realizations']}, "
            f"{r.get('within_radius')}/{r['realizations']} within radius {v.converged_radius:g}"
            + (f", settled offset median {off['median']:.2g}" if off else "")
            if oc
            else ""
        )
        parts.append(f"{lab} {_pm(r.get('err_G'))}{loops}")
    lines.append(f"At b = {b}, error of [A_z, B_z] vs the unquantized EDMD: " + "; ".join(parts) + ".")
    if frame.reference_loop is not None:
        ref = frame.reference_loop
        off = float(ref.settled_offset[0]) if len(ref.settled_offset) else float("nan")
        settled = f", settled offset {off:.2g} (what the dictionary alone leaves)" if off == off else ""
        lines.append(f"The unquantized EDMD's Koopman MPC: {ref.outcome[0]}{settled}.")
    lines.append(bcls_exactness(v))
    if "LS" in frame.labels:  # what the error plot draws, in the plot's own words
        note = limit_note(frame.series(), bool(v.guard))
        lines.append(
            "LS's large-data limit (dashed): "
            + (
                f"not drawn: {note.rstrip('.')}."
                if note
                else "drawn (polynomial dictionary, subtractive dither, no overload)."
            )
        )
    lines.append("Not certified: " + NO_CERTIFICATES + ".")
    if frame.data_report:
        lines.append(frame.data_report + ".")
    return "  \n".join(lines)


class KoopmanRenderer:
    """Remembers what one tab drew last for a nonlinear plant (as :class:`~app.dashboard.render.Renderer`)."""

    def __init__(self) -> None:
        self.figures: dict[str, Any] = {}
        self._rows_key: Any = None
        self._current_key: Any = None
        self._style = "normal"

    def render(self, frame: Any, axes: str | None = None, narrow: bool = False) -> Render:
        """What to push for ``frame``; ``narrow``: the tab is a phone's (its style wins over presenter mode)."""
        presenter = bool(getattr(frame.values, "presenter", False))
        style = "phone" if narrow else "presenter" if presenter else "normal"
        if style != self._style:  # every figure is rebuilt in the other style
            self.figures, self._rows_key, self._current_key = {}, None, None
            self._style = style
        out: dict[str, Any] = {}
        scene = summary = None
        curves = [v.name for v in registry.KOOPMAN_VIEWS if v.depends == CURVES]
        current = [v.name for v in registry.KOOPMAN_VIEWS if v.depends == CURRENT]
        key = (frame.bits, tuple(id(frame.models[lab]) for lab in frame.labels), frame.values)
        rows_key = (
            frame.values,
            tuple((lab, b, repr(r)) for lab in frame.labels for b, r in sorted(frame.rows[lab].items())),
        )
        if frame.stage == "current" or key != self._current_key:
            scene, summary = koopman_scene(frame), koopman_summary(frame)
            if key != self._current_key:
                out.update(koopman_figures(frame, current))
                self._current_key = key
        if rows_key != self._rows_key:
            out.update(koopman_figures(frame, curves))
            self._rows_key = rows_key
            summary = koopman_summary(frame)
        else:
            for name in curves:
                fig = self.figures.get(name)
                if fig is not None and any(sh.name == CURRENT_B for sh in fig.layout.shapes):
                    out[name] = move_current_bits(fig, frame.bits)
        restyle = STYLES[style]
        out = {n: restyle(f, inplace=True) if f is not self.figures.get(n) else f for n, f in out.items()}
        self.figures.update(out)
        aspects = {name: plot_aspect(style, name, fig) for name, fig in out.items()}
        return Render(scene, summary, {name: Wire(fig) for name, fig in out.items()}, aspects)
