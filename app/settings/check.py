"""A value of one setting checked by type before any conversion, as strictly as the CLI checks it.

Used for every value the dashboard's panel holds (anything can come over its websocket) and every value of
a settings file: an integer setting takes a whole number (3.7, "5" and true are refused), a boolean one
true or false ("false", 1 and [0] are refused), a number is finite and inside the setting's range, a
choice is one of the offered ones, a text is text of bounded size. Every refusal is one line naming the
setting (its panel label).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from typing import Any

from qsid_core import QsidError

from .schema import Setting, resolve

__all__ = ["InputError", "check_setting", "MAX_TEXT", "MAX_NESTING", "NUMBER_MAX"]

#: Longest text accepted in a text box (characters).
MAX_TEXT = 20_000
#: Deepest bracket nesting accepted in a text box (a matrix needs 2: ``[[1, 2], [3, 4]]``).
MAX_NESTING = 4
#: Largest magnitude of a number setting without its own ``max``.
NUMBER_MAX = 1e9


class InputError(QsidError):
    """A value typed, chosen, sent or loaded for a setting cannot be used; the message says why, in plain words."""


def _show(value: object) -> str:
    return repr(value)[:40]


def _number(label: str, value: object, integer: bool) -> float:
    """``value`` as a float, refused unless it is a finite number (a whole one if ``integer``); bools are no numbers."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        what = "a whole number" if integer else "a number"
        raise InputError(f"{label}: expected {what}, got {type(value).__name__} {_show(value)}")
    try:
        x = float(value)
    except OverflowError:
        raise InputError(f"{label}: {str(value)[:20]}… is far too large") from None
    if not math.isfinite(x):
        raise InputError(f"{label}: {value!r} is not a finite number")
    if integer and x != int(x):
        raise InputError(f"{label}: needs a whole number, got {value}")
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


def _in_range(s: Setting, x: float, value: object, lab: str, slider: bool) -> None:
    if slider and s.control == "slider" and s.slider is not None:
        lo, hi, _ = resolve(s.slider)
        if not lo - 1e-9 <= x <= hi + 1e-9:
            raise InputError(f"{lab}: {value:g} is outside the slider's range {lo:g} … {hi:g}")
        return
    if not slider and s.min is None and s.max is None:
        return  # the engine checks its own range
    hi = s.max if s.max is not None else NUMBER_MAX
    if s.min is not None and s.min > 0 and x < s.min:
        raise InputError(f"{lab} must be a positive number (at least {s.min:g}); got {value:g}")
    lo = s.min if s.min is not None else -hi
    if not lo <= x <= hi:
        raise InputError(f"{lab}: {value:g} is outside {lo:g} … {hi:g}")


def check_setting(
    s: Setting, value: Any, options: Sequence[str] | None = None, name: str | None = None, slider: bool = True
) -> Any:
    """``value`` if it is allowed for setting ``s``, converted only after the check (a whole float to int,
    a list of numbers to a tuple); ``options``: a dropdown's choices now (default: the setting's);
    ``name``: how messages name the setting (default: its panel label); ``slider``: a slider's value must lie
    on the slider (False: only the setting's ``min``/``max``, for values set by code rather than in the panel).

    Raises
    ------
    InputError
        One line naming the setting and what is allowed.
    """
    lab = s.label if name is None else name
    if s.type is bool:
        if not isinstance(value, bool):
            raise InputError(f"{lab}: expected on/off (true or false), got {_show(value)}")
        return value
    if s.type in (int, float):
        x = _number(lab, value, s.type is int)
        _in_range(s, x, value, lab, slider)
        return int(x) if s.type is int else x
    if s.type is tuple:
        if not isinstance(value, (list, tuple)) or len(value) > 1000:
            raise InputError(f"{lab}: expected a list of numbers, got {_show(value)}")
        return tuple(_number(lab, x, False) for x in value)
    if not isinstance(value, str):
        raise InputError(f"{lab}: expected text, got {type(value).__name__} {_show(value)}")
    allowed = tuple(options) if options is not None else tuple(resolve(s.choices))
    if s.control == "dropdown" or allowed:
        if allowed and value not in allowed:
            raise InputError(f"{lab}: {value[:40]!r} is not one of {', '.join(map(str, allowed))}")
        return value
    if len(value) > MAX_TEXT:
        raise InputError(f"{lab}: the text is too long ({len(value):,} characters; at most {MAX_TEXT:,})")
    if _nesting(value) > MAX_NESTING:
        raise InputError(
            f"{lab}: too many nested brackets (at most {MAX_NESTING}; a matrix needs 2, e.g. [[1, 2], [3, 4]])"
        )
    return value
