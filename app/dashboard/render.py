"""Decides what one tab redraws for each frame (the views: :data:`app.figures.registry.VIEWS`, read at call time)."""

from __future__ import annotations

from dataclasses import dataclass

from app.figures.phase_scene import SceneView, scene_view
from app.figures import registry
from app.figures.axes import finite_axes
from app.figures.traces import move_current_bits
from app.figures.view import CURRENT, CURVES

from .frames import Frame
from .summary import summary_markdown

__all__ = ["Render", "Renderer", "build_figures"]


def build_figures(frame: Frame, which=None) -> dict:
    """Plotly figures of the registered views for ``frame`` (all, or the names in ``which``).

    Rows may be partial: missing word lengths are simply absent from the curves.
    """
    return {v.name: finite_axes(v.build(frame)) for v in registry.VIEWS if which is None or v.name in which}


@dataclass
class Render:
    """What to push to a tab for one frame (None / missing = leave as is)."""

    scene: SceneView | None
    summary: str | None
    figures: dict


class Renderer:
    """Remembers what one tab drew last, so each frame redraws only what changed.

    * a "current" frame redraws the 3-D view and the summary, rebuilds the
      ``"current"`` views if b or the models changed, and moves the current-b
      marker of the ``"curves"`` views;
    * a "curves" frame rebuilds the ``"curves"`` views only if their rows
      changed (a pure b change leaves them alone and just moves the marker).
    """

    def __init__(self):
        self.figures: dict = {}
        self._rows_key = None
        self._current_key: dict = {}

    def render(self, frame: Frame, axes: str | None = None) -> Render:
        out: dict = {}
        scene = summary = None
        curves = [v.name for v in registry.VIEWS if v.depends == CURVES]
        if frame.stage == "current":
            scene = scene_view(frame, axes)
            summary = summary_markdown(frame)
            models = (frame.bits, tuple(id(frame.idents[lab]) for lab in frame.labels))
            keys = {v.name: (v.key(frame) if v.key is not None else models)
                    for v in registry.VIEWS if v.depends == CURRENT}
            redo = [name for name, k in keys.items() if self._current_key.get(name, self) != k]
            out.update(build_figures(frame, redo))
            self._current_key.update(keys)
        rows_key = (frame.labels, frame.true_cost,
                    tuple((lab, b, repr(r)) for lab in frame.labels for b, r in sorted(frame.rows[lab].items())))
        if frame.stage == "curves" and rows_key != self._rows_key:
            out.update(build_figures(frame, curves))
            self._rows_key = rows_key
        else:
            for name in curves:
                if name in self.figures:
                    out[name] = move_current_bits(self.figures[name], frame.bits)
        self.figures.update(out)
        return Render(scene, summary, out)
