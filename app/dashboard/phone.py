"""The phone layout of one tab, and how the server learns that the window is a phone's.

viser's browser client never tells the server the window's size or address. It does send, with every camera
message, the size of its 3-D canvas (``client.camera.image_width`` / ``image_height``, public). When a tab
connects no panel is docked yet, so that canvas is the whole window; and in viser's own phone layout (windows
up to 36em = 576 px wide) every panel goes into one bottom sheet over the canvas, which therefore stays the
whole window. So:

* a tab whose canvas is clearly taller than wide when it connects (width / height below :data:`NARROW`) is a
  phone held upright, or a window as narrow;
* while a tab is in the phone layout, camera messages keep telling the window's shape: turned sideways (width
  / height above :data:`WIDE_AGAIN`), it gets the laptop layout back;
* a desktop window made narrow after the page opened keeps the laptop layout until it is reloaded (its docked
  panels take part of the canvas there, so the canvas's shape no longer says the window's).

The phone layout (:class:`PhoneLayout`, applied by the tab's worker): the plots in the sheet one group at a
time, each plot as wide as the sheet (:func:`app.figures.presenter.phone_figure`: panels stacked, text of 12
px), the plots section open; the word-length slider near the top with the lesson's text below it; the settings
tabs and the summary behind one button, so that the plots follow the slider; presenter mode off (its panel
widths mean nothing in the sheet); the 3-D box framed in the part of the scene the sheet leaves free. The
sheet itself is made as wide as the window and at most half its height by a style sheet,
:data:`PHONE_SHEET_CSS` (sent to each tab through viser's public ``add_html``; its selectors match the inline
styles :data:`SHEET_SOURCE` of viser's sheet, which a test checks against the installed client): viser draws it
20em wide and up to 60 % high.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

__all__ = ["PhoneLayout", "NARROW", "WIDE_AGAIN", "SHEET", "canvas_aspect", "SETTINGS_LABELS", "PHONE_SHEET_CSS"]
__all__ += ["SHEET_SOURCE"]

#: A canvas narrower than this (width / height) when the tab connects is a phone's (upright phones are 0.4-0.6;
#: with the browser's bars 0.65-0.7; a laptop window 1.3-1.8).
NARROW = 0.75
#: In the phone layout, a canvas wider than this (width / height) is a phone turned sideways.
WIDE_AGAIN = 1.0
#: The share of the window's height the bottom sheet may cover (the style sheet's max-height).
SHEET = 0.5
#: viser's phone layout (up to its 36em breakpoint) draws every panel in one bottom sheet, 20em wide and up to 60 %
#: high (inline styles, client/src/ControlPanel/BottomPanel.tsx): stretched across the window, at most half as high.
PHONE_SHEET_CSS = (
    '<style>@media (max-width: 36em) {.mantine-Paper-root[style*="position: fixed"][style*="20em"]'
    "{width: 100vw !important; max-height: 50% !important;}"
    '.mantine-Paper-root[style*="position: fixed"] [style*="width: 20em"]{width: 100vw !important;}'
    # a dropdown's list (the "show" and "lesson" choices) opens as a sheet at the window's foot, always on
    # screen, instead of beside its input in a sheet that may sit half off the window
    ".mantine-Select-dropdown{position: fixed !important; left: 8px !important; right: 8px !important;"
    "top: auto !important; bottom: 8px !important; width: auto !important; max-height: 45vh !important;"
    "overflow-y: auto !important;}"
    ".mantine-Select-dropdown .mantine-Popover-arrow{display: none !important;}"
    "}"
    # (every window) viser draws a slider's number box without its slider's "disabled" (a follower's b): inert
    # like the slider
    ".mantine-Flex-root:has(> .mantine-Slider-root [data-disabled]) > .mantine-NumberInput-root"
    "{pointer-events: none; opacity: 0.6;}"
    "</style>"
)
#: The inline styles of viser's bottom sheet (as its client's source writes them) that the selectors rely on.
SHEET_SOURCE = ('position: "fixed"', 'width: "20em"', 'maxHeight: "60%"')
#: The button that shows or hides the settings tabs and the summary on a phone.
SETTINGS_LABELS = ("⚙ all settings", "⚙ hide the settings")


def canvas_aspect(camera: Any) -> float | None:
    """Width / height of the tab's 3-D canvas from its last camera message (None before one arrived)."""
    w, h = getattr(camera, "image_width", 0), getattr(camera, "image_height", 0)
    return float(w) / float(h) if w and h and w > 0 and h > 0 else None


class PhoneLayout:
    """Whether one tab is a phone's, and its layout (from the worker thread only; callbacks only mark it).

    Parameters
    ----------
    gui : client.gui
    camera : client.camera
        Its canvas size says whether the window is narrow (module docstring).
    controls : GuiElements
    plots_panel : the docked plots panel (a section of the sheet on a phone)
    portrait : :class:`~app.dashboard.scene.PhasePortrait`
    on_change : callable()
        Marks the tab dirty (the worker then calls :meth:`apply`).
    aspect : float, optional
        Width / height of the canvas when the tab connected, read before the tab docked any panel (default: the
        camera's now; once the tab's own panels are laid out, the canvas no longer has the window's shape).
    """

    def __init__(
        self, gui, camera, controls, plots_panel, portrait, on_change: Callable[[], None], aspect: float | None = None
    ):
        self.controls = controls
        self.plots_panel = plots_panel
        self.portrait = portrait
        self._lock = threading.Lock()
        self._on_change = on_change
        if aspect is None:
            aspect = canvas_aspect(camera)
        self._narrow = aspect is not None and aspect < NARROW  # the whole window: no panel of the tab's docked yet
        self._aspect = aspect or 1.0
        self._settings = False  # the settings shown on a phone
        self.narrow = False  # what is applied
        self._orders = (float(controls.lesson_text.order), float(controls["bits"].order))
        self.button = gui.add_button(SETTINGS_LABELS[0], visible=False, hint="The settings tabs and the summary")
        self.button.order = float(controls.status.order) + 0.5
        self.button.on_click(lambda _e: self.toggle_settings())
        camera.on_update(self._camera)

    @property
    def wanted(self) -> bool:
        """Whether the tab should have the phone layout (what the camera last said)."""
        with self._lock:
            return self._narrow

    def _camera(self, camera) -> None:
        """(viser's thread) A camera message: in the phone layout the canvas is the window, so its shape counts."""
        aspect = canvas_aspect(camera)
        with self._lock:
            if not self._narrow or aspect is None:
                return
            self._aspect = aspect
            turned = aspect > WIDE_AGAIN
            if turned:
                self._narrow = False
        if turned:
            self._on_change()

    def toggle_settings(self) -> None:
        with self._lock:
            self._settings = not self._settings
        self._on_change()

    def apply(self) -> bool:
        """Switch to or from the phone layout (and show or hide its settings); True if anything changed."""
        with self._lock:
            narrow, settings, aspect = self._narrow, self._settings, self._aspect
        c = self.controls
        shown = not narrow or settings
        changed = narrow != self.narrow or c.tabs.visible != shown
        label = SETTINGS_LABELS[1 if settings else 0]
        if self.button.label != label:
            self.button.label = label
        for h in (c.tabs, c.summary_folder):
            if h.visible != shown:
                h.visible = shown
        if narrow == self.narrow:
            return changed
        self.narrow = narrow
        self.button.visible = narrow
        c["presenter"].visible = not narrow
        lesson, bits = self._orders  # on a phone the lesson's text goes below the slider
        c.lesson_text.order = bits + 0.25 if narrow else lesson
        if narrow:
            self.plots_panel.expand()  # its section of the sheet open: the plots are what a phone is for
            self.portrait.look(aspect, free=1.0 - SHEET)
        else:
            self.portrait.look()
        return True
