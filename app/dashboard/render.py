"""Decides what one tab redraws for each frame (the views: :data:`app.figures.registry.VIEWS`, read at call time)."""

from __future__ import annotations

from dataclasses import dataclass

from app.figures import registry
from app.figures.axes import finite_axes
from app.figures.compare import PINNED_VIEWS, overlay_pinned
from app.figures.phase_scene import SceneView, scene_view
from app.figures.presenter import PHONE_WIDTH, PRESENTER_SIZE, legible_figure, phone_figure, presenter_figure
from app.figures.raw import Wire
from app.figures.traces import CURRENT_B, move_current_bits
from app.figures.view import CURRENT, CURVES

from .frames import Frame
from .presenter import PLOT_ASPECT
from .summary import summary_markdown

__all__ = ["Render", "Renderer", "build_figures", "STYLES", "plot_aspect"]

#: The figures' style per layout: a laptop's, presenter mode's (a projector) and a phone's.
STYLES = {"normal": legible_figure, "presenter": presenter_figure, "phone": phone_figure}


def plot_aspect(style: str, name: str, fig) -> float:
    """Height / width of plot ``name`` drawn in ``style``: the view's own, or as high as the styled figure."""
    height = fig.layout.height
    if style == "presenter" and height:
        return max(PLOT_ASPECT, round(float(height) / PRESENTER_SIZE[0], 3))
    if style == "phone" and height:
        return round(float(height) / PHONE_WIDTH, 3)
    return next(v.aspect for v in registry.VIEWS + registry.KOOPMAN_VIEWS if v.name == name)  # read at call time


def build_figures(frame: Frame, which=None) -> dict:
    """Plotly figures of the registered views for ``frame`` (all, or the names in ``which``).

    Rows may be partial: missing word lengths are simply absent from the curves.
    """
    figs = {v.name: v.build(frame) for v in registry.VIEWS if which is None or v.name in which}
    pinned = getattr(frame, "pinned", None)
    if pinned is not None:  # a pinned earlier result: its curves dashed on top
        for v in registry.VIEWS:
            if v.name in figs and v.name in PINNED_VIEWS:
                overlay_pinned(figs[v.name], v.build(pinned), f"pinned b={pinned.bits}")
    return {name: finite_axes(fig) for name, fig in figs.items()}


@dataclass
class Render:
    """What to push to a tab for one frame (None / missing = leave as is)."""

    scene: SceneView | None
    summary: str | None
    figures: dict
    #: view name -> height / width of its plot (for the figures pushed)
    aspects: dict


class Renderer:
    """Remembers what one tab drew last, so each frame redraws only what changed.

    * a "current" frame redraws the 3-D view and the summary, rebuilds the
      ``"current"`` views whose key changed (default: b or the models), and moves the current-b
      marker of the ``"curves"`` views;
    * a "curves" frame rebuilds the ``"curves"`` views only if their rows
      changed (a pure b change leaves them alone and just moves the marker).
    """

    def __init__(self):
        self.figures: dict = {}
        self._rows_key = None
        self._current_keys: dict = {}
        self._style = "normal"

    def render(self, frame: Frame, axes: str | None = None, narrow: bool = False) -> Render:
        """What to push for ``frame``; ``narrow``: the tab is a phone's (its style wins over presenter mode)."""
        out: dict = {}
        presenter = bool(getattr(frame.values, "presenter", False))
        style = "phone" if narrow else "presenter" if presenter else "normal"
        if style != self._style:  # every figure is rebuilt in the other style
            self.figures, self._rows_key, self._current_keys = {}, None, {}
            self._style = style
        scene = summary = None
        curves = [v.name for v in registry.VIEWS if v.depends == CURVES]
        if frame.stage == "current":
            scene = scene_view(frame, axes)
            summary = summary_markdown(frame)
            models = (frame.bits, tuple(id(frame.idents[lab]) for lab in frame.labels))
            todo = []
            for v in registry.VIEWS:
                if v.depends == CURRENT:
                    key = v.key(frame) if v.key is not None else models
                    if self._current_keys.get(v.name) != key:
                        todo.append(v.name)
                        self._current_keys[v.name] = key
            out.update(build_figures(frame, todo))
        rows_key = (
            frame.labels,
            frame.true_cost,
            id(frame.pinned),
            frame.values.compare_bits,
            frame.values.axes,
            frame.values.target,
            frame.values.cost_gap,
            tuple((lab, b, repr(r)) for lab in frame.labels for b, r in sorted(frame.rows[lab].items())),
        )
        if frame.stage == "curves" and rows_key != self._rows_key:
            out.update(build_figures(frame, curves))
            self._rows_key = rows_key
        else:
            for name in curves:  # only plots with a current-b marker are touched (and re-sent)
                fig = self.figures.get(name)
                if fig is not None and any(sh.name == CURRENT_B for sh in fig.layout.shapes):
                    out[name] = move_current_bits(fig, frame.bits)
        # the layout's style (smallest text, line widths, panels stacked), once, on the figures just built
        restyle = STYLES[style]
        out = {
            name: restyle(fig, inplace=True) if name not in self.figures or fig is not self.figures[name] else fig
            for name, fig in out.items()
        }
        self.figures.update(out)
        aspects = {name: plot_aspect(style, name, fig) for name, fig in out.items()}
        # viser's plot handle calls figure.to_json(): Wire's skips plotly's deep copy (raw.to_json)
        return Render(scene, summary, {name: Wire(fig) for name, fig in out.items()}, aspects)
