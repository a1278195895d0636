"""Presenter mode (a lecture-hall layout) and the auto-play over the word length, for one tab.

* :class:`PresenterLayout`: with the panel's "presenter" box ticked, the left panel and the plots panel are
  narrowed so that the 3-D scene gets more than half of a 1366 px window, panel text is at least
  :data:`PANEL_FONT` px (a style sheet sent to the page), the scene's lines are thicker and its labels bigger;
  the plots' own style is :func:`app.figures.presenter.presenter_figure` (applied by the renderer).
* :class:`AutoPlay`: b from 1 to 16, about one word length per :data:`STEP_SECONDS`. The tab's worker loop
  asks :meth:`AutoPlay.wait_time` how long it may sleep and calls :meth:`AutoPlay.step` only when the tab is
  idle (every change drawn), so the next b is set only once the previous one is drawn or after
  :data:`STEP_SECONDS`, whichever is later: auto-play never queues work. The button's callback and the inputs'
  callbacks only change the state under a lock; the worker sets the slider and the button's label.
"""

from __future__ import annotations

import threading
import time

from .controls import PLAY_LABEL
from .settings import ALL_BITS

__all__ = ["PresenterLayout", "AutoPlay", "STEP_SECONDS", "PANEL_FONT", "LEFT_WIDTH", "RIGHT_WIDTH"]

#: Seconds between two word lengths of the auto-play (at least: a slow frame delays the next step).
STEP_SECONDS = 1.0
#: Smallest panel text in presenter mode (px).
PANEL_FONT = 16
#: Panel widths in presenter mode (px): at 1366 px the 3-D scene keeps 1366 - 290 - 370 - 4 = 702 px (> 683).
LEFT_WIDTH, RIGHT_WIDTH = 290, 370
#: The left panel's normal width (viser's "large" control width).
NORMAL_LEFT = 384

#: Panel text of at least PANEL_FONT px everywhere outside plots and the 3-D canvas (plotly sets its own sizes
#: inline on SVG text, which this does not touch).
STYLE = (
    "<style>body :not(svg):not(svg *):not(canvas)"
    f"{{font-size:max({PANEL_FONT}px,1em) !important;line-height:1.35}}</style>"
)


class PresenterLayout:
    """Applies presenter mode to one tab (from its worker thread only)."""

    def __init__(self, gui, plots_panel, portrait, normal_right: float):
        self.gui = gui
        self.plots_panel = plots_panel
        self.portrait = portrait
        self.normal_right = normal_right
        self.on = False
        self.style = gui.add_html("", visible=False)

    def apply(self, on: bool) -> bool:
        """Switch presenter mode on or off; True if it changed."""
        on = bool(on)
        if on == self.on:
            return False
        self.on = on
        self.gui.main_panel.set_width(LEFT_WIDTH if on else NORMAL_LEFT)
        self.plots_panel.set_width(RIGHT_WIDTH if on else self.normal_right)
        self.style.content = STYLE if on else ""
        self.style.visible = on
        self.portrait.set_presenter(on)
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
