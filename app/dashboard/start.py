"""The guided start: the lesson a new tab of ``qsid-dashboard`` opens on when nothing else was asked for.

It is one row of :data:`app.dashboard.lessons.LESSONS` (``(name, title, text, settings, plot)``, as
:class:`~app.dashboard.lessons.Lesson` takes it): what the three panels show, which slider to move first and
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
    f"qsid replays the letter by {LETTER} ({LETTER_URL}): a dc motor's A and B are identified by least "
    "squares from data quantized to b bits, and an MPC built on that model steers the true motor. Three panels: "
    "this one (settings; the numbers in the Summary at its bottom), the 3-D scene (the closed loops of the "
    "identified models, LS blue and BCLS red, around the true-model loop in black) and the plots (errors "
    "against b; the show list picks others). Move the word length b first (just below, or ▶ auto-play): the "
    "errors fall about 0.3 decades per bit and the coloured loops close in on the black one. Theorem 1's line "
    "is faded because the motor's angle is an integrator (its data never settle, so Ψ Ψᵀ/T has no limit; the "
    "theorem1 lesson shows the theorem hold on the Boeing 747), and the letter's δ(ε) is a bound only where it "
    "is below ρ, here from b = 5 on. Next pick **fig1** in the lesson list (the letter's Figure 1 at its data "
    f"size); ε, ρ, δ, BCLS and the other words: the glossary, {GLOSSARY_DOC}.",
    _SETTINGS,
    "error",
)


def opens_on_start(lesson: str | None, settings: object | None, system: str) -> bool:
    """True if ``qsid-dashboard`` opens new tabs on the start lesson: no ``--lesson``, no ``--settings`` or
    plant file, and the default plant (the text is about it)."""
    return lesson is None and settings is None and system == _SETTINGS["system"]
