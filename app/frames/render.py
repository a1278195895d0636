"""Decides what one view of a study redraws for each frame, of a linear or a nonlinear plant alike: the views the
frame's result offers (:data:`app.figures.registry.VIEWS` or :data:`~app.figures.registry.KOOPMAN_VIEWS`, read at
call time), the 3-D scene and the summary (:mod:`app.frames.summary`); and what a draw pushed (:class:`Drawn`,
each figure's JSON made once, :class:`Sent`), which the dashboard shares with the tabs following it."""

from __future__ import annotations

import threading
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import Any, TypeVar, cast

from app.figures import registry
from app.figures.axes import finite_axes
from app.figures.compare import PINNED_VIEWS, overlay_pinned
from app.figures.lifted_scene import lifted_scene
from app.figures.phase_scene import SceneView, scene_view
from app.figures.presenter import PHONE_WIDTH, PRESENTER_SIZE, legible_figure, phone_figure, presenter_figure
from app.figures.raw import Wire
from app.figures.traces import MarkedAt, has_current_bits
from app.figures.view import CURRENT, CURVES

from .cache import SharedCache
from .frame import Frame, KoopmanFrame, lifted
from .summary import summary_markdown

__all__ = ["Render", "Renderer", "Figures", "FIGURES_MB", "build_figures", "STYLES", "PLOT_ASPECT", "plot_aspect"]
__all__ += ["Sent", "Drawn"]

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


class Sent:
    """A figure as pushed to a plot handle, with the handle's height / width (``aspect``): its JSON made once (by
    the first handle given it, or by :class:`Figures`), then reused by every handle given it (other tabs showing
    the same state, a leader's followers). viser's plot handle calls :meth:`to_json`; every other attribute is the
    figure's. Never changed once made."""

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


T = TypeVar("T")

#: Budget of :class:`Figures` (MB, estimated): the default view's twelve figures, scene and summary at one b take
#: ~1.9 MB at the interactive scale (measured with tracemalloc), so it holds some two dozen states drawn.
FIGURES_MB = 48


def _kept_bytes(item: Any) -> int:
    """Estimated memory of a kept figure (its JSON and the figure's own numbers and dicts), a summary's text or a
    3-D scene's arrays."""
    if isinstance(item, Sent):  # (tracemalloc: the default view's figures hold ~3 times their JSON's length)
        return 3 * len(item.to_json()) + 4096
    if isinstance(item, str):
        return len(item) + 64
    return 4096 + sum(int(getattr(v, "nbytes", 64)) for v in vars(item).values())


class Figures:
    """The figures drawn in any tab, each built, styled and made JSON once, then pushed by every tab that draws
    the same thing (a class on one link: one render per state, not one per tab); a linear plant's 3-D scene and
    summary at the current b too.

    A key says everything a figure is made from (:class:`Renderer` makes them: the view, the layout, the plant's
    kind, the panel's values and what the view reads of the frame beyond them); the figures are never changed
    once kept. A bounded LRU (:class:`~app.frames.cache.SharedCache`, ``max_bytes``); a figure one tab is building
    is waited for by another tab that needs it, not built twice. ``builds`` and ``reused`` count (for tests and
    benchmarks)."""

    def __init__(self, max_bytes: int = FIGURES_MB * 2**20):
        self.store = SharedCache(max_bytes, keep=16, size=_kept_bytes)
        self._lock = threading.Lock()  # guards the counts (tabs' workers build and reuse at once)
        self.builds = 0
        self.reused = 0

    def get(self, key: Hashable, make: Callable[[], T]) -> T:
        """The figure (or scene, or summary) kept under ``key``; else the one another tab is making now; else
        ``make()``, kept."""
        flights = self.store.flights
        while True:
            got = self.store.get(key)
            if got is None:
                mine, theirs = flights.claim([key])
                if not theirs:
                    return self._make(key, make, mine)
                ok, got = flights.wait(theirs[key])
                if not ok:  # its maker failed: make it here
                    continue
            with self._lock:
                self.reused += 1
            return cast(T, got)

    def _make(self, key: Hashable, make: Callable[[], T], mine: list) -> T:
        try:
            got = self.store.get(key)  # kept between the look and the claim
            if got is None:
                got = make()
                if isinstance(got, Sent):
                    got.to_json()  # (JSON made here, once, not by the first tab's push)
                self.store[key] = got
                with self._lock:
                    self.builds += 1
        except BaseException:
            self.store.flights.abort(mine)
            raise
        self.store.flights.land(key, got)
        return cast(T, got)

    def clear(self) -> None:
        self.store.clear()


@dataclass
class Render:
    """What to push to a tab for one frame (None / missing = leave as is): the figures each with its plot's
    height / width (:attr:`Sent.aspect`)."""

    scene: SceneView | None
    summary: str | None
    figures: dict[str, Sent]


class Renderer:
    """Remembers what one tab drew last, so each frame redraws only what changed.

    * a linear plant's "current" frame redraws the 3-D view and the summary and rebuilds the ``"current"``
      views whose key changed (default: b or the models); a nonlinear plant's does so whenever b, its models or
      the settings changed;
    * the ``"curves"`` views are rebuilt only if their rows changed (a linear plant's in a "curves" frame); a
      pure b change leaves them alone and just moves their current-b marker (a copy of the figure with the
      marker moved, pushed only if the marker moved).

    ``shared``: the server's :class:`Figures`, where every figure is made once for all tabs (None: each is made
    here). Only the views that draw a pinned result (:data:`~app.figures.compare.PINNED_VIEWS`) are made here
    while the tab pins one.
    """

    def __init__(self, shared: Figures | None = None):
        self.shared = shared
        self.reset()

    def reset(self) -> None:
        """Forget what was drawn: the next frame redraws every view."""
        self.figures: dict[str, Sent] = {}
        #: curves view -> (its key, the figure as built, whether it has a current-b marker, the b it was built at,
        #: the b its marker shows now)
        self._bases: dict[str, tuple[Hashable | None, Sent, bool, int, int]] = {}
        self._rows_key: Any = None
        self._current_keys: dict[str, Any] = {}
        self._models_key: tuple | None = None  # (a nonlinear plant's b, models and settings last drawn)
        self._style = "normal", "linear"
        self._texts: dict[int, tuple[Any, str]] = {}  # id(row) -> (the row, its repr), for the rows last drawn

    def _rows(self, frame: Frame | KoopmanFrame) -> tuple:
        """The frame's rows as compared: (label, b, the row's repr). Rows are read-only and a tab's computation
        reuses the rows it built (:func:`~qsid_core.studies.full_row`), so each row's text is made once while
        drawn (a b change redrew 32 rows' reprs per frame)."""
        out, texts = [], {}  # (kept beyond one frame: a b change draws the current b's row, then every row)
        for lab in frame.labels:
            for b, r in sorted(frame.rows[lab].items()):
                held = self._texts.get(id(r))
                text = held[1] if held is not None and held[0] is r else repr(r)
                texts[id(r)] = (r, text)
                out.append((lab, b, text))
        if len(self._texts) > 1024:  # (the rows of many settings drawn: those of this frame are kept)
            self._texts = texts
        else:
            self._texts.update(texts)
        return tuple(out)

    def _key(self, frame: Frame | KoopmanFrame, name: str, *what: Hashable) -> Hashable | None:
        """The key of view ``name`` made from ``frame`` and ``what`` (None: made for this tab only)."""
        if self.shared is None or (frame.pinned is not None and name in PINNED_VIEWS):
            return None
        return (name, self._style, frame.values, *what)

    def _shared(self, key: Hashable | None, make: Callable[[], T]) -> T:
        """``make()`` kept under ``key`` in :attr:`shared` for every tab (made here alone: no key, or no store)."""
        return make() if key is None or self.shared is None else self.shared.get(key, make)

    def _made(self, key: Hashable | None, frame: Frame | KoopmanFrame, name: str) -> Sent:
        """View ``name`` of ``frame`` built in this tab's layout (or the same, made already, from ``shared``)."""
        style = self._style[0]

        def make() -> Sent:
            fig = STYLES[style](build_figures(frame, [name])[name], inplace=True)  # the layout's style, once
            # viser's plot handle calls figure.to_json(): Wire's skips plotly's deep copy (raw.to_json)
            return Sent(Wire(fig), plot_aspect(style, name, fig))

        return self._shared(key, make)

    def _current(self, frame: Frame | KoopmanFrame, views: tuple, default: Hashable) -> dict[str, Sent]:
        """The ``"current"`` views whose key (their own, else ``default``) changed since drawn."""
        out = {}
        for v in views:
            if v.depends == CURRENT:
                key = v.key(frame) if v.key is not None else default
                if self._current_keys.get(v.name) != key:
                    self._current_keys[v.name] = key
                    # (beyond the values, a current view reads only the results at b: the data-length study)
                    shared = self._key(frame, v.name, CURRENT, frame.datalength is not None)
                    out[v.name] = self._made(shared, frame, v.name)
        return out

    def _curves(self, frame: Frame | KoopmanFrame, names: list[str], rows: tuple, rebuild: bool) -> dict[str, Sent]:
        """The ``"curves"`` views built anew (``rebuild``), else those whose current-b marker moved (``rows``: the
        frame's rows as compared)."""
        out = {}
        # what a curves view reads beyond the panel's values: the rows so far, how many, the budget study
        drawn = (CURVES, rows, frame.done, frame.total, frame.budget is not None)
        for name in names:
            if rebuild:
                key = self._key(frame, name, *drawn)
                fig = self._made(key, frame, name)
                self._bases[name] = (key, fig, has_current_bits(fig.wire.figure), frame.bits, frame.bits)
                out[name] = fig
                continue
            base = self._bases.get(name)
            if base is None or not base[2] or base[4] == frame.bits:
                continue  # no marker, or it marks this b already: nothing to push
            key, built, marked, made_at, _shown = base
            self._bases[name] = (key, built, marked, made_at, frame.bits)
            out[name] = built if frame.bits == made_at else self._moved(key, built, frame.bits)
        return out

    def _moved(self, key: Hashable | None, built: Sent, bits: int) -> Sent:
        """Curves view ``built`` (kept under ``key``) with its current-b marker at ``bits``."""

        def make() -> Sent:
            return Sent(MarkedAt(built.wire.figure, bits), built.aspect)

        return self._shared(None if key is None else (key, bits), make)

    def render(self, frame: Frame | KoopmanFrame, axes: str | None = None, narrow: bool = False) -> Render:
        """What to push for ``frame``; ``narrow``: the tab is a phone's (its style wins over presenter mode)."""
        presenter = bool(getattr(frame.values, "presenter", False))
        nonlinear = lifted(frame)
        style = "phone" if narrow else "presenter" if presenter else "normal"
        if (style, "nonlinear" if nonlinear else "linear") != self._style:  # every figure is rebuilt
            self.reset()
            self._style = style, "nonlinear" if nonlinear else "linear"
        views = registry.KOOPMAN_VIEWS if nonlinear else registry.VIEWS
        curves = [v.name for v in views if v.depends == CURVES]
        rows = self._rows(frame)
        out: dict[str, Sent] = {}
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
            if frame.stage == "current":  # (both read the panel's values and the results at b: made once)
                scene = self._shared(("scene", frame.values, axes), lambda: scene_view(frame, axes))
                summary = self._shared(("summary", frame.values), lambda: summary_markdown(frame))
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
            self._rows_key = rows_key
        out.update(self._curves(frame, curves, rows, rebuild))
        self.figures.update(out)
        return Render(scene, summary, out)


@dataclass
class Drawn:
    """What one draw pushed to a tab: the 3-D scene and the summary (None: unchanged) and the figures redrawn."""

    scene: Any = None
    summary: str | None = None
    figures: dict[str, Sent] = field(default_factory=dict)
