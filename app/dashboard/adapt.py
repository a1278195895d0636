"""The panel fitted to what was picked in it: the kind of plant, linear or nonlinear (:class:`KindSwitch`), and the
lesson, marked "modified from the lesson" with a button back once the panel drifts from it (:class:`LessonMark`;
which settings drift: :mod:`app.lessons.drift`).

Threads: runs in the tab's worker (see the list in :mod:`app.dashboard.session`); the mark's button only marks the
tab dirty.
"""

from __future__ import annotations

from typing import Any

from app.lessons.drift import lesson_drift, lesson_markdown
from app.lessons.table import BACK_LABEL, NONE, lesson_values
from app.settings.values import LINEAR_ONLY, NONLINEAR_ONLY, Values, is_nonlinear, scale_label, switch_defaults

from .controls import read_values

__all__ = ["KindSwitch", "LessonMark"]


class KindSwitch:
    """Shows the panel inputs of the kind of plant picked (linear or nonlinear) and, when the kind changes, moves
    the settings still at the one kind's defaults to the other's (:func:`~app.settings.values.switch_defaults`;
    not when a lesson set the panel: a lesson's settings are complete)."""

    def __init__(self) -> None:
        self.nonlinear: bool | None = None  # the kind last shown (None: not yet)
        self.plant = "van-der-pol"  # the nonlinear plant last picked

    def apply(self, session: Any) -> bool:
        """Fit ``session``'s panel to the plant picked; True if panel values were changed here."""
        c = session.controls
        system = str(c["system"].value)
        nonlinear = is_nonlinear(system)
        changed = False
        if self.nonlinear is not None and nonlinear != self.nonlinear:
            values = read_values(c)
            lesson = str(c["lesson"].value)
            les = lesson_values(lesson) if lesson != NONE else None
            if les is None or les.system != system:  # (a lesson's own settings are complete: kept)
                plant = system if nonlinear else self.plant
                for name, value in switch_defaults(values, plant, nonlinear, also=les).items():
                    c[name].value = value
                    changed = True
        if nonlinear:
            self.plant = system
        if nonlinear != self.nonlinear:
            for name in LINEAR_ONLY:  # (the 3-D axes choice: only where a linear system has more than one)
                c[name].visible = not nonlinear and (name != "axes" or len(c[name].options) > 1)
            for name in NONLINEAR_ONLY:
                c[name].visible = nonlinear
            for button, paper in zip(c.scale_buttons, (True, False)):
                button.label = scale_label(system, paper)
            if c.theory_note is not None:
                c.theory_note.visible = nonlinear
            session.views.set_kind(nonlinear)
            self.nonlinear = nonlinear
        if nonlinear:  # (the linear code keeps fixed_range's visibility in read_values)
            c["fixed_range"].visible = c["range_mode"].value == "fixed"
        return changed


class LessonMark:
    """The "modified from the lesson" mark above a lesson's text and the button back (one per tab).

    Parameters
    ----------
    gui : client.gui
    text : the lesson text's markdown handle (the button goes right below it)
    on_back : callable()
        The button was pressed (the tab then sets the lesson's settings again).
    """

    def __init__(self, gui, text, on_back):
        self.text = text
        self.drift: tuple[str, ...] = ()
        self.wanted = False  # the button was pressed and the tab has not set the lesson again yet
        self.back = gui.add_button(BACK_LABEL, visible=False, order=float(text.order) + 0.5)
        self._on_back = on_back
        self.back.on_click(lambda _e: self.press())

    def press(self) -> None:
        """The button: ask the tab to set the lesson's settings again."""
        self.wanted = True
        self._on_back()

    def take(self) -> bool:
        """True once after the button was pressed (the tab's worker then sets the lesson again)."""
        wanted, self.wanted = self.wanted, False
        return wanted

    def show(self, values: Values) -> None:
        """Mark (or unmark) the text for ``values`` (from the tab's worker)."""
        drift = lesson_drift(values.lesson, values)
        if drift != self.drift:
            self.drift = drift
            self.text.content = lesson_markdown(values.lesson, drift)
            self.back.visible = bool(drift)
