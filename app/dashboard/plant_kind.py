"""The panel fitted to the kind of plant picked, linear or nonlinear (:class:`KindSwitch`).

Threads: runs in the tab's worker (see the list in :mod:`app.dashboard.session`).
"""

from __future__ import annotations

from typing import Any

from .controls import read_values
from .koopman_settings import LINEAR_ONLY, NONLINEAR_ONLY, is_nonlinear, scale_label, switch_defaults
from .lessons import NONE, lesson_values

__all__ = ["KindSwitch"]


class KindSwitch:
    """Shows the panel inputs of the kind of plant picked (linear or nonlinear) and, when the kind changes, moves
    the settings still at the one kind's defaults to the other's (:func:`~app.dashboard.koopman_settings.switch_defaults`;
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
