"""The guided start: the lesson a new tab of ``qsid-dashboard`` opens on when nothing else was asked for.

It is one row of :data:`app.lessons.table.LESSONS` (``(name, title, text, settings, plot)``, as
:class:`~app.lessons.table.Lesson` takes it): what the three panels show, which slider to move first and
what to look for, on the default plant at the default settings, with the letter it reproduces cited and the
``fig1`` lesson as the next step. Every claim is asserted at these settings by
``tests/dashboard/test_dashboard_start.py``.
"""

from __future__ import annotations

from typing import Any

__all__ = ["START", "START_LESSON", "LETTER", "LETTER_URL", "GLOSSARY_DOC", "opens_on_start"]

#: The lesson's name (the selector's entry and ``--lesson start``).
START = "start"
#: The letter qsid reproduces, as it is cited in the panel, the README and the docs.
LETTER = (
    "Ataei, Maity, Goswami, *Model Predictive Control with System Identification from Quantized Data*, arXiv 2503.19102"
)
LETTER_URL = "https://arxiv.org/abs/2503.19102"
#: Where the glossary is: the dashboard serves no docs, so the page in the source tree (and once built).
GLOSSARY_DOC = "docs/glossary.rst (glossary.html in the built docs)"

#: The settings the text is about: the default plant (a different plant marks the text as modified).
_SETTINGS: dict[str, Any] = dict(system="dc-motor")

START_LESSON: tuple[str, str, str, dict[str, Any], str] = (
    START,
    "Start here",
    f"qsid replays the letter by {LETTER} ({LETTER_URL}) on a dc motor: A and B identified by least squares "
    "from data quantized to b bits, an MPC built on them run on the true motor. Panels: the settings here (the "
    "numbers in the Summary below), the closed loops in 3-D (LS blue, BCLS red, the true model's black) and the "
    "plots of the errors against b (show: Identification). Move b first: the errors fall about 0.3 decades per bit and the coloured "
    "loops close in on the black one. Theorem 1's line is faded because the motor's angle is an integrator (its "
    "data never settle; the theorem1 lesson shows the theorem hold on the Boeing 747), and δ(ε) is a bound only "
    "below ρ, here from b = 5 on. Next: the **fig1** lesson; the symbols: the glossary, "
    f"{GLOSSARY_DOC}.",
    _SETTINGS,
    "error",
)


def opens_on_start(lesson: str | None, settings: object | None, system: str) -> bool:
    """True if ``qsid-dashboard`` opens new tabs on the start lesson: no ``--lesson``, no ``--settings`` or
    plant file, and the default plant (the text is about it)."""
    return lesson is None and settings is None and system == _SETTINGS["system"]
