"""Presenter mode (a lecture-hall layout) and the auto-play over the word length, for one tab.

* :class:`PresenterLayout`: with the panel's "presenter" box ticked, ONE view fills the room beside a narrow
  left panel: either the plots (the lesson's key plot first, every plot as high as the visible part of the
  plots panel, the panel as wide as the window allows, the 3-D scene hidden) or the 3-D scene (the plots panel
  minimized, the camera framing the box in the room left). One button under the auto-play switches between
  the two. The slider, the auto-play and the switch come first in the left panel, the lesson's text below
  them (in the window at 1366 × 768 whatever the lesson's length). Panel text is at least :data:`PANEL_FONT` px (a style sheet sent to the page), the scene's lines are
  thicker and its labels bigger; the plots' own style (text ≥ 18 px, thick lines, panels stacked) is
  :func:`app.figures.presenter.presenter_figure` (applied by the renderer). A phone has no presenter mode.
* :class:`AutoPlay`: b from 1 to 16, about one word length per :data:`STEP_SECONDS`. The tab's worker loop
  asks :meth:`AutoPlay.wait_time` how long it may sleep and calls :meth:`AutoPlay.step` only when the tab is
  idle (every change drawn), so the next b is set only once the previous one is drawn or after
  :data:`STEP_SECONDS`, whichever is later: auto-play never queues work. The button's callback and the inputs'
  callbacks only change the state under a lock; the worker sets the slider and the button's label.
"""

from __future__ import annotations

import threading
import time

from app.settings.values import ALL_BITS

from .controls import PLAY_LABEL

__all__ = [
    "PresenterLayout",
    "AutoPlay",
    "STEP_SECONDS",
    "PANEL_FONT",
    "LEFT_WIDTH",
    "WIDE",
    "LEFT_SHARE",
    "SCENE_ASPECT",
    "SHOW_SCENE",
    "SHOW_PLOT",
]

#: Seconds between two word lengths of the auto-play (at least: a slow frame delays the next step).
STEP_SECONDS = 1.0
#: Smallest panel text in presenter mode (px).
PANEL_FONT = 16
#: The left panel's width in presenter mode showing the 3-D scene (px).
LEFT_WIDTH = 290
#: Presenter mode showing the plot: the left panel and the plots panel are asked for more than any window
#: (:data:`WIDE` in all), in the ratio :data:`LEFT_SHARE` : 1 − LEFT_SHARE. viser's dock then scales both to
#: the window less its 120 px minimum of 3-D canvas, so without knowing the window's width (the server is not
#: told it) the left panel gets 20 % of it (249 px at 1366, 360 px at 1920) and the plots the rest.
WIDE, LEFT_SHARE = 20000.0, 0.2
#: Width / height of the 3-D canvas beside the left panel in presenter mode (at least; the camera frames the
#: box in it).
SCENE_ASPECT = 1.35
#: The switch's labels: what pressing it shows.
SHOW_SCENE, SHOW_PLOT = "⇄ show the 3-D scene", "⇄ show the plot"
#: The switch's and, in presenter mode, the lesson text's place after the auto-play (in order units; the view-code
#: lines follow the auto-play at +0.001 .. +0.004: :func:`app.dashboard.share.add_code_panel`).
SWITCH_AT, TEXT_AT = 0.0002, 0.0005
#: The left panel's normal width (viser's "large" control width).
NORMAL_LEFT = 384

#: The narrowest a plot is drawn in presenter mode (px): its layout is made for 1000 px, and squeezed much
#: narrower (a window under ~750 px, or one narrowed to a phone's width) its margins would leave the plot no
#: room, on which plotly.js throws and the whole page goes blank. Narrower panels scroll sideways instead.
MIN_PLOT_WIDTH = 700
#: Panel text of at least PANEL_FONT px everywhere outside plots and the 3-D canvas (plotly sets its own sizes
#: inline on SVG text, which this does not touch); every plot at least MIN_PLOT_WIDTH px wide.
STYLE = (
    "<style>body :not(svg):not(svg *):not(canvas)"
    f"{{font-size:max({PANEL_FONT}px,1em) !important;line-height:1.35}}"
    f"div:has(> .js-plotly-plot){{min-width:{MIN_PLOT_WIDTH}px}}</style>"
)


class PresenterLayout:
    """Applies presenter mode to one tab (from its worker thread only; the switch's click only marks it).

    Parameters
    ----------
    gui : client.gui
    plots_panel : the docked plots panel
    portrait : :class:`~app.dashboard.scene.PhasePortrait`
    normal_right : float
        The plots panel's width outside presenter mode (px).
    after : a GUI handle
        The switch goes right below it (the auto-play button).
    on_change : callable()
        Marks the tab dirty (the worker then calls :meth:`apply`).
    """

    def __init__(self, gui, plots_panel, portrait, normal_right: float, after=None, on_change=None):
        self.gui = gui
        self.plots_panel = plots_panel
        self.portrait = portrait
        self.normal_right = normal_right
        self.on = False
        self.scene_shown = False  # presenter mode: the 3-D scene (True) or the plots (False)
        self._want_scene = False
        self.style = gui.add_html("", visible=False)
        self.switch = gui.add_button(SHOW_SCENE, visible=False, hint="Presenter mode shows one view: this or that")
        #: where the switch goes: right below the auto-play (before the view-code lines there)
        self._after = float(after.order) if after is not None else float(self.switch.order)
        if after is not None:
            self.switch.order = self._after + SWITCH_AT
        #: the lesson's text (and what goes with it) and their orders outside presenter mode (:meth:`move_below`)
        self._text: list = []
        self._text_orders: list[float] = []
        self._lock = threading.Lock()
        self._on_change = on_change or (lambda: None)
        self.switch.on_click(lambda _e: self.toggle())

    def move_below(self, handles: list) -> None:
        """In presenter mode these (the lesson's text, its "back" button) go below the slider, the auto-play and
        the switch, so that a lesson of any length leaves them in the window at 1366 × 768; back in place when
        presenter mode is off."""
        self._text = list(handles)
        self._text_orders = [float(h.order) for h in handles]
        if self.on:
            self._place_text(True)

    def _place_text(self, on: bool) -> None:
        for i, (h, order) in enumerate(zip(self._text, self._text_orders)):
            want = self._after + TEXT_AT + 0.0001 * i if on else order
            if float(h.order) != want:
                h.order = want

    def toggle(self) -> None:
        """The switch: show the other view (applied by the worker)."""
        with self._lock:
            self._want_scene = not self._want_scene
        self._on_change()

    def apply(self, on: bool, narrow: bool = False) -> bool:
        """Presenter mode on or off, showing the plots or the 3-D scene; a phone (``narrow``) has none of it
        (its panels are one sheet). Returns True if anything changed."""
        on = bool(on) and not narrow
        with self._lock:
            scene = self._want_scene and on
        if on == self.on and scene == self.scene_shown:
            return False
        if on != self.on:
            self.style.content = STYLE if on else ""
            self.style.visible = on
            self.portrait.set_presenter(on)
            self.switch.visible = on
            self._place_text(on)
        was_scene = self.scene_shown
        self.on, self.scene_shown = on, scene
        # one view at a time: the scene hidden while the plot fills the window (the dock keeps a strip of it)
        self.portrait.show(scene or not on)
        if scene:  # the scene beside the left panel, the box framed in it
            self.gui.main_panel.set_width(LEFT_WIDTH)
            self.plots_panel.minimize()
            self.portrait.look(SCENE_ASPECT)
        elif on:  # the plots as wide as the window allows (see WIDE)
            self.gui.main_panel.set_width(WIDE * LEFT_SHARE)
            self.plots_panel.expand()
            self.plots_panel.set_width(WIDE * (1 - LEFT_SHARE))
        elif not narrow:
            self.gui.main_panel.set_width(NORMAL_LEFT)
            self.plots_panel.expand()
            self.plots_panel.set_width(self.normal_right)
        if was_scene and not scene:
            self.portrait.look()  # back where every tab starts
        self.switch.label = SHOW_PLOT if scene else SHOW_SCENE
        return True


class AutoPlay:
    """The auto-play state of one tab: off, playing or paused (thread-safe)."""

    def __init__(self, button, bits_input, on_change):
        self.button = button
        self.bits = bits_input
        self.on_change = on_change  # marks the tab dirty (the worker then re-reads wait_time)
        self._lock = threading.Lock()
        self.state = "off"
        self._restart = False
        self._last = 0.0
        self._label = PLAY_LABEL
        self.steps = 0  # word lengths set by the auto-play so far (tests, benchmarks)
        self.stopped_by_user = False

    def press(self) -> None:
        """The button: start (from b = 1), pause, or resume (from the b shown)."""
        with self._lock:
            if self.state == "playing":
                self.state = "paused"
            else:
                self._restart = self.state == "off" or int(self.bits.value) >= ALL_BITS[-1]
                self.state = "playing"
                self._last = 0.0
            self.stopped_by_user = False
        self.on_change()

    def user_changed(self) -> None:
        """A change made in the browser: the auto-play stops (paused, so it can be resumed)."""
        with self._lock:
            if self.state == "playing":
                self.state = "paused"
                self.stopped_by_user = True

    def wait_time(self) -> float | None:
        """Seconds the idle worker may sleep before the next step (None: not playing)."""
        with self._lock:
            if self.state != "playing":
                return None
            return max(0.0, self._last + STEP_SECONDS - time.monotonic())

    def step(self) -> bool:
        """Set the next word length (called by the worker when idle and :meth:`wait_time` has passed)."""
        with self._lock:
            if self.state != "playing" or time.monotonic() < self._last + STEP_SECONDS:
                return False
            b = int(self.bits.value)
            nb = ALL_BITS[0] if self._restart else b + 1
            self._restart = False
            if nb > ALL_BITS[-1]:
                self.state = "off"
                return False
            self._last = time.monotonic()
            self.steps += 1
        self.bits.value = nb  # the input's callback marks the tab dirty (not a change of the person's)
        if nb == ALL_BITS[-1]:
            with self._lock:
                if self.state == "playing":
                    self.state = "off"
        return True

    def show(self) -> None:
        """The button's label for the current state (from the worker)."""
        with self._lock:
            state, by_user = self.state, self.stopped_by_user
        if state == "playing":
            label = "■ pause auto-play"
        elif state == "paused":
            label = "▶ resume auto-play" + (" (stopped by your change)" if by_user else "")
        else:
            label = PLAY_LABEL
        if label != self._label:
            self._label = label
            self.button.label = label
