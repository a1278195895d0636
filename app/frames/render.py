"""Decides what one view of a study redraws for each frame, of a linear or a nonlinear plant alike: the views the
frame's result offers (:data:`app.figures.registry.VIEWS` or :data:`~app.figures.registry.KOOPMAN_VIEWS`, read at
call time), the 3-D scene and the summary (:mod:`app.frames.summary`); and what a draw pushed (:class:`Drawn`,
each figure's JSON made once, :class:`Sent`), which the dashboard shares with the tabs following it."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from app.figures import registry
from app.figures.axes import finite_axes
from app.figures.compare import PINNED_VIEWS, overlay_pinned
from app.figures.lifted_scene import lifted_scene
from app.figures.phase_scene import SceneView, scene_view
from app.figures.presenter import PHONE_WIDTH, PRESENTER_SIZE, legible_figure, phone_figure, presenter_figure
from app.figures.raw import Wire
from app.figures.traces import CURRENT_B, move_current_bits
from app.figures.view import CURRENT, CURVES

from .frame import Frame, KoopmanFrame, lifted
from .summary import summary_markdown

__all__ = ["Render", "Renderer", "build_figures", "STYLES", "PLOT_ASPECT", "plot_aspect", "Sent", "Drawn"]

#: The figures' style per layout: a laptop's, presenter mode's (a projector) and a phone's.
STYLES = {"normal": legible_figure, "presenter": presenter_figure, "phone": phone_figure}
#: Height / width of a plot in presenter mode: one view fills the dashboard's plots panel under its header at
#: 1366 × 768 (~1000 × 600 px) and at 1920 × 1080 (~1430 × 860 px); a view of many rows is taller
#: (:func:`plot_aspect` sets each plot's aspect from its figure).
PLOT_ASPECT = PRESENTER_SIZE[1] / PRESENTER_SIZE[0]


def plot_aspect(style: str, name: str, fig) -> float:
    """Height / width of plot ``name`` drawn in ``style``: the view's own, or as high as the styled figure."""
    height = fig.layout.height
    if style == "presenter" and height:
        return max(PLOT_ASPECT, round(float(height) / PRESENTER_SIZE[0], 3))
    if style == "phone" and height:
        return round(float(height) / PHONE_WIDTH, 3)
    return next(v.aspect for v in registry.VIEWS + registry.KOOPMAN_VIEWS if v.name == name)  # read at call time


def build_figures(frame: Frame | KoopmanFrame, which=None) -> dict:
    """Plotly figures of the views ``frame``'s result offers (all, or the names in ``which``).

    Rows may be partial: missing word lengths are simply absent from the curves. A pinned earlier result of a
    linear plant is drawn dashed on top of its error, cost and bound plots.
    """
    views = registry.KOOPMAN_VIEWS if lifted(frame) else registry.VIEWS
    figs = {v.name: v.build(frame) for v in views if which is None or v.name in which}
    pinned = getattr(frame, "pinned", None)
    if pinned is not None and not lifted(frame):
        for v in views:
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

    * a linear plant's "current" frame redraws the 3-D view and the summary and rebuilds the ``"current"``
      views whose key changed (default: b or the models); a nonlinear plant's does so whenever b, its models or
      the settings changed;
    * the ``"curves"`` views are rebuilt only if their rows changed (a linear plant's in a "curves" frame); a
      pure b change leaves them alone and just moves their current-b marker.
    """

    def __init__(self):
        self.figures: dict = {}
        self._rows_key = None
        self._current_keys: dict = {}
        self._models_key: tuple | None = None  # (a nonlinear plant's b, models and settings last drawn)
        self._style = "normal", "linear"

    def _current(self, frame, views, default) -> dict:
        """The ``"current"`` views whose key (their own, else ``default``) changed since drawn."""
        todo = []
        for v in views:
            if v.depends == CURRENT:
                key = v.key(frame) if v.key is not None else default
                if self._current_keys.get(v.name) != key:
                    todo.append(v.name)
                    self._current_keys[v.name] = key
        return build_figures(frame, todo) if todo else {}

    def render(self, frame: Frame | KoopmanFrame, axes: str | None = None, narrow: bool = False) -> Render:
        """What to push for ``frame``; ``narrow``: the tab is a phone's (its style wins over presenter mode)."""
        presenter = bool(getattr(frame.values, "presenter", False))
        nonlinear = lifted(frame)
        style = "phone" if narrow else "presenter" if presenter else "normal"
        if (style, "nonlinear" if nonlinear else "linear") != self._style:  # every figure is rebuilt
            self.figures, self._rows_key, self._current_keys, self._models_key = {}, None, {}, None
            self._style = style, "nonlinear" if nonlinear else "linear"
        views = registry.KOOPMAN_VIEWS if nonlinear else registry.VIEWS
        curves = [v.name for v in views if v.depends == CURVES]
        rows = tuple((lab, b, repr(r)) for lab in frame.labels for b, r in sorted(frame.rows[lab].items()))
        out: dict = {}
        scene = summary = None
        if nonlinear:
            assert isinstance(frame, KoopmanFrame)
            key = (frame.bits, tuple(id(frame.models[lab]) for lab in frame.labels), frame.values)
            if frame.stage == "current" or key != self._models_key:
                scene, summary = lifted_scene(frame), summary_markdown(frame)
                self._models_key = key
                out.update(self._current(frame, views, key))
            rows_key: tuple = (frame.values, rows, id(frame.budget))
            rebuild = rows_key != self._rows_key
            if rebuild:
                summary = summary_markdown(frame)
        else:
            assert isinstance(frame, Frame)
            if frame.stage == "current":
                scene, summary = scene_view(frame, axes), summary_markdown(frame)
                out.update(
                    self._current(frame, views, (frame.bits, tuple(id(frame.idents[lab]) for lab in frame.labels)))
                )
            v = frame.values
            rows_key = (
                frame.labels,
                frame.true_cost,
                id(frame.pinned),
                v.compare_bits,
                v.axes,
                v.target,
                v.cost_gap,
                rows,
                id(frame.budget),
            )
            rebuild = frame.stage == "curves" and rows_key != self._rows_key
        if rebuild:
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


class Sent:
    """A figure as pushed to a plot handle, with the handle's height / width (``aspect``): its JSON made once (by
    the first handle given it), then reused by every follower's handle. viser's plot handle calls
    :meth:`to_json`; every other attribute is the figure's."""

    __slots__ = ("wire", "json", "aspect")

    def __init__(self, wire: Any, aspect: float):
        self.wire = wire  # an app.figures.raw.Wire (or a plotly figure)
        self.json: str | None = None
        self.aspect = aspect

    def to_json(self) -> str:
        if self.json is None:
            self.json = self.wire.to_json()
        return self.json

    def __getattr__(self, name: str) -> Any:
        return getattr(self.wire, name)


@dataclass
class Drawn:
    """What one draw pushed to a tab: the 3-D scene and the summary (None: unchanged) and the figures redrawn."""

    scene: Any = None
    summary: str | None = None
    figures: dict[str, Sent] = field(default_factory=dict)
