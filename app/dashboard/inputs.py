"""Server-side check of every value a tab's panel holds, before anything is computed.

A browser only offers what the panel allows, but anything can be sent over the
websocket: a slider at 400 or 1e308, NaN, a seed of 10**400, a 5,000-deep
bracket in a matrix. :func:`check_panel` reads the raw handle values and raises
:class:`~app.dashboard.settings.InputError` in plain words (the tab keeps its
last good view); only then are the values converted (:func:`read_values`).
"""

from __future__ import annotations

import math
import numbers
from typing import TYPE_CHECKING, Any

import numpy as np

from .controls import CONTROLS, Control
from .settings import LOG_MAX, LOG_MIN, InputError

if TYPE_CHECKING:
    from collections.abc import Sequence

    from .controls import GuiElements
    from .frames import Frame

__all__ = ["check_panel", "check_value", "unusable", "MAX_TEXT", "MAX_NESTING", "NUMBER_MAX"]

#: Longest text accepted in a text box (characters).
MAX_TEXT = 20_000
#: Deepest bracket nesting accepted in a text box (a matrix needs 2: ``[[1, 2], [3, 4]]``).
MAX_NESTING = 4
#: Largest value of the panel's number boxes (seeds are 32-bit; rho stays far from overflow).
NUMBER_MAX = {"dither_seed": 2**32 - 1, "data_seed": 2**32 - 1, "rho": 1e6}


def _number(c_label: str, value: object, integer: bool) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(f"{c_label}: expected a number, got {type(value).__name__}")
    try:
        x = float(value)
    except OverflowError:
        raise InputError(f"{c_label}: {str(value)[:20]}… is far too large") from None
    if not math.isfinite(x):
        raise InputError(f"{c_label}: {value!r} is not a finite number")
    if integer and x != int(x):
        raise InputError(f"{c_label}: needs a whole number, got {value}")
    return x


def _nesting(text: str) -> int:
    depth = deepest = 0
    for ch in text:
        if ch in "[(":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "])":
            depth -= 1
    return deepest


def check_value(c: Control, value: Any, options: Sequence[str] | None = None) -> None:
    """Raise :class:`InputError` unless ``value`` is allowed for control ``c`` (``options``: a dropdown's now)."""
    lab = c.label
    if c.kind == "slider":
        assert c.lo is not None and c.hi is not None  # every slider has a range
        x = _number(lab, value, c.convert is int)
        if not c.lo - 1e-9 <= x <= c.hi + 1e-9:
            raise InputError(f"{lab}: {value:g} is outside the slider's range {c.lo:g} … {c.hi:g}")
    elif c.kind == "number":
        x = _number(lab, value, c.convert is int)
        hi = NUMBER_MAX.get(c.name, 1e9)
        if c.lo is not None and c.lo > 0 and x < c.lo:
            raise InputError(f"{lab} must be a positive number (at least {c.lo:g}); got {value:g}")
        if not (c.lo if c.lo is not None else -hi) <= x <= hi:
            raise InputError(f"{lab}: {value:g} is outside {c.lo:g} … {hi:g}")
    elif c.kind == "checkbox":
        if not isinstance(value, bool):
            raise InputError(f"{lab}: expected on/off, got {value!r}")
    elif c.kind == "dropdown":
        allowed = tuple(options if options is not None else c.choices)
        if value not in allowed:
            raise InputError(f"{lab}: {str(value)[:40]!r} is not one of {', '.join(map(str, allowed))}")
    else:  # text
        if not isinstance(value, str):
            raise InputError(f"{lab}: expected text, got {type(value).__name__}")
        if len(value) > MAX_TEXT:
            raise InputError(f"{lab}: the text is too long ({len(value):,} characters; at most {MAX_TEXT:,})")
        if _nesting(value) > MAX_NESTING:
            raise InputError(
                f"{lab}: too many nested brackets (at most {MAX_NESTING}; a matrix needs 2, e.g. [[1, 2], [3, 4]])"
            )


def check_panel(el: GuiElements) -> None:
    """Check every input of one tab's panel (``GuiElements``) as it is now.

    Raises
    ------
    InputError
        The first bad value, naming the input and what is allowed.
    """
    for c in CONTROLS:
        h = el.inputs[c.name]
        check_value(c, h.value, getattr(h, "options", None) if c.kind == "dropdown" else None)
    for kind, sliders in (("Q", el.q_sliders), ("R", el.r_sliders)):
        for s in sliders:
            x = _number(s.label, s.value, False)
            if not LOG_MIN <= x <= LOG_MAX:
                raise InputError(
                    f"{s.label}: {s.value:g} is outside the slider's range {LOG_MIN:g} … {LOG_MAX:g} "
                    f"(log10 of the {kind} weight)"
                )


def unusable(frame: Frame) -> str | None:
    """Why a "current" frame must not be shown as a result (every identification failed, ε not finite), or None."""
    if frame.stage != "current":
        return None
    for ident in frame.idents.values():
        if not np.all(np.isfinite(ident.eps)):
            return (
                f"the quantizer step ε at b = {frame.bits} is not a finite number (the range is too wide "
                "for floating point); choose a narrower range"
            )
    if frame.idents and all(np.all(ident.failed) for ident in frame.idents.values()):
        ident = next(iter(frame.idents.values()))
        why = "; ".join(ident.notes[:2]) or "no reason given"
        return f"every identification failed at b = {frame.bits} (all {len(ident.failed)} dither realizations): {why}"
    return None
