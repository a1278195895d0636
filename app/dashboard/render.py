"""Decides what one tab redraws for each frame (the views: :data:`app.figures.registry.VIEWS`, read at call time)."""

from __future__ import annotations

from collections.abc import Collection
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
    """Remembers what one tab drew last, so each frame redraws only what changed and what is shown.

    * a "current" view is rebuilt when its key changed (default: b or the models);
    * a "curves" view is rebuilt by a "curves" frame whose rows changed; otherwise only its current-b
      marker moves (a pure b change leaves the curves alone);
    * only the views in ``shown`` (the plots panel's group) are built. A hidden view whose inputs changed is
      *stale* (forgotten as built) and is built when a frame is rendered with it shown: the tab then redraws
      its last frame, nothing is computed (:meth:`stale` lists them).

    What a figure was built from is kept as a key of object identities; the renderer holds the last frame and
    the last "curves" frame it rendered, so the objects behind every key it keeps are alive and no identity is
    reused by a newer result while a view is hidden.
    """

    def __init__(self):
        self.figures: dict = {}
        #: view name -> what its figure was built from (a current view's key, a curves view's rows)
        self._built: dict = {}
        #: curves view name -> the b its current-b marker is at
        self._marks: dict = {}
        self._held: dict = {}  # "last", "curves" -> the frames rendered last (see the class docstring)
        self._style = "normal"

    @staticmethod
    def _wants(frame: Frame) -> tuple[dict, object]:
        """``(current view name -> its key, the rows' key)``: what each view of ``frame`` is built from."""
        models = (frame.bits, tuple(id(frame.idents[lab]) for lab in frame.labels))
        current = {
            v.name: v.key(frame) if v.key is not None else models for v in registry.VIEWS if v.depends == CURRENT
        }
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
        return current, rows_key

    def _changed(self, frame: Frame, current: dict, rows_key: object) -> list[str]:
        """Every view (shown or not) whose figure ``frame`` changes (``current``, ``rows_key``: :meth:`_wants`): a
        "current" view whose key differs, and on a "curves" frame a "curves" view whose rows differ."""
        out = []
        for v in registry.VIEWS:
            if v.depends == CURRENT:
                if self._built.get(v.name) != current[v.name]:
                    out.append(v.name)
            elif frame.stage == "curves" and self._built.get(v.name) != rows_key:
                out.append(v.name)
        return out

    def stale(self, frame: Frame, shown: Collection[str] | None = None) -> list[str]:
        """The views of ``shown`` (None: all) that rendering ``frame`` would build (their figure is out of date)."""
        return [name for name in self._changed(frame, *self._wants(frame)) if shown is None or name in shown]

    def render(
        self, frame: Frame, axes: str | None = None, narrow: bool = False, shown: Collection[str] | None = None
    ) -> Render:
        """What to push for ``frame``; ``narrow``: the tab is a phone's (its style wins over presenter mode);
        ``shown``: the names of the views the tab shows (None: every view)."""
        presenter = bool(getattr(frame.values, "presenter", False))
        style = "phone" if narrow else "presenter" if presenter else "normal"
        if style != self._style:  # every figure is rebuilt in the other style
            self.figures, self._built, self._marks = {}, {}, {}
            self._style = style
        scene = summary = None
        if frame.stage == "current":
            scene = scene_view(frame, axes)
            summary = summary_markdown(frame)
        current, rows_key = self._wants(frame)
        todo = []
        for name in self._changed(frame, current, rows_key):
            if shown is None or name in shown:
                todo.append(name)
            else:  # hidden: stale until its group is shown
                self._built.pop(name, None)
        out = build_figures(frame, todo)
        for name in todo:
            self._built[name] = current.get(name, rows_key)
            self._marks[name] = frame.bits
        for v in registry.VIEWS:  # the shown curves kept: a plot whose current-b marker moves is re-sent
            fig = self.figures.get(v.name)
            if v.depends != CURVES or v.name in out or fig is None or (shown is not None and v.name not in shown):
                continue
            if self._marks.get(v.name) != frame.bits and any(sh.name == CURRENT_B for sh in fig.layout.shapes):
                out[v.name] = move_current_bits(fig, frame.bits)
                self._marks[v.name] = frame.bits
        self._held["last"] = frame
        if frame.stage == "curves":
            self._held["curves"] = frame
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
