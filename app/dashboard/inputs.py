"""Server-side check of every value a tab's panel holds, before anything is computed.

A browser only offers what the panel allows, but anything can be sent over the
websocket: a slider at 400 or 1e308, NaN, 3.7 for an integer, "no" for a checkbox, a seed of
10**400, a 5,000-deep bracket in a matrix. :func:`check_sent` checks each value as it arrives,
before viser converts it to the input's type (the input keeps its last value);
:func:`check_panel` reads the raw handle values before a computation and raises
:class:`~app.settings.values.InputError` in plain words (the tab keeps its
last good view); only then are the values converted (:func:`read_values`). The rules are the
settings table's (:func:`app.settings.check.check_setting`), the same as for a settings file.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from app.settings.check import MAX_NESTING, MAX_TEXT, check_setting
from app.settings.schema import Setting
from app.settings.values import LOG_MAX, LOG_MIN, InputError

from .controls import CONTROLS, Control

if TYPE_CHECKING:
    from collections.abc import Awaitable, Callable, Mapping, Sequence

    from app.frames.frame import Frame

    from .controls import GuiElements

__all__ = [
    "check_panel",
    "check_value",
    "check_sent",
    "sent_guard",
    "blur_clamp",
    "unusable",
    "MAX_TEXT",
    "MAX_NESTING",
    "TYPING_PAUSE",
]

#: seconds a refused value's input waits, with no newer value, before it is sent the value in use: a number typed
#: key by key is sent as it grows ("0", "0.", "0.00" on the way to "0.005"), and setting the box back at the
#: first refused prefix would turn the next keys into "1.005"
TYPING_PAUSE = 1.5

#: A weight slider's value (log10 of the weight; the sliders are made per system, not from the table).
_LOG_WEIGHT = Setting("log_weight", float, 0.0, "log10 weight", "slider", slider=(LOG_MIN, LOG_MAX, 0.1))


def _number(label: str, value: object) -> float:
    """A weight slider's value, checked (InputError naming the slider ``label``)."""
    return float(check_setting(_LOG_WEIGHT, value, name=label))


def check_value(c: Control, value: Any, options: Sequence[str] | None = None) -> None:
    """Raise :class:`InputError` unless ``value`` is allowed for control ``c`` (``options``: a dropdown's now).

    The value's type is checked before anything is converted (:func:`app.settings.check.check_setting`).
    """
    assert c.setting is not None  # every control is made from a setting
    check_setting(c.setting, value, options if options is not None else (c.choices or None))


def check_sent(el: GuiElements | None, handle: Any, updates: Mapping[str, Any]) -> str | None:
    """Why a value sent over the websocket for ``handle`` is refused before viser converts it, or None.

    viser turns a sent value into the input's type before any callback (3.7 into 3 for an integer slider,
    "no" into True for a checkbox); this check runs first, with the panel's own rules.
    """
    if el is None or "value" not in updates:
        return None
    value = updates["value"]
    label = str(getattr(handle, "label", "an input"))
    try:
        if any(handle is s for s in (*el.q_sliders, *el.r_sliders)):
            _number(label, value)
        else:
            c = next((c for c in CONTROLS if el.inputs.get(c.name) is handle), None)
            if c is not None:
                check_value(c, value, getattr(handle, "options", None) if c.kind == "dropdown" else None)
    except InputError as exc:
        why = str(exc).removeprefix(f"{label}: ")
        return f"{label}: the value sent ({repr(value)[:40]}) was refused ({why}); the input keeps its last value"
    return None


def blur_clamp(handle: Any, value: Any) -> float | None:
    """What a browser's number box sends for ``value`` on leaving the box if ``value`` is out of the input's bounds
    (``handle.min``/``max``): the nearest bound (Mantine's NumberInput clamps on blur); None if it sends nothing."""
    lo, hi = getattr(handle, "min", None), getattr(handle, "max", None)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return None
    clamped = min(max(value, lo if lo is not None else -math.inf), hi if hi is not None else math.inf)
    return float(clamped) if clamped != value else None


def sent_guard(
    check: Callable[[Any, Mapping[str, Any]], str | None],
    on_reject: Callable[[str, Any], None],
    on_accept: Callable[[Any], None] | None = None,
) -> Callable[[Any, dict, Callable[[], Awaitable[None]]], Awaitable[bool]]:
    """The guard of one tab's input messages (:func:`app.dashboard.viserfix.guard_updates`, which sends the tab the
    value in use again when the guard returns False): a value ``check`` refuses is dropped, and one viser cannot
    convert (``apply()`` raises) is explained; both said by ``on_reject(text, handle)``. A value taken is said by
    ``on_accept(handle)``. The guard returns whether the tab's box shows the value in use.

    A slider's box has bounds: a refused value out of them stays in the box until the value in use arrives, and if
    the box is left before that, the browser sends its bound (:func:`blur_clamp`), then shows the value in use
    sent back. That bound, as the tab's next message, is taken like any value, and sent back too: the box shows
    what the results are for. (A number box has no bound in the browser: it never sends a value of its own.)"""
    refused: tuple[Any, float | None] = (None, None)  # the input of the value just refused, and its box's bound

    def reject(text: str, handle: Any, updates: Mapping[str, Any]) -> bool:
        nonlocal refused
        on_reject(text, handle)
        refused = (handle, blur_clamp(handle, updates.get("value")))
        return False

    async def guard(handle: Any, updates: dict, apply: Callable[[], Awaitable[None]]) -> bool:
        nonlocal refused
        (last, bound), refused = refused, (None, None)
        why = check(handle, updates)
        if why is not None:
            return reject(why, handle, updates)
        try:
            await apply()
        except Exception as exc:
            sent = ", ".join(f"{k} = {str(v)[:40]!r}" for k, v in updates.items())
            return reject(
                f"{getattr(handle, 'label', None) or 'an input'}: the value sent ({sent}) was refused "
                f"({type(exc).__name__}: {str(exc)[:80]}); the input keeps its last value",
                handle,
                updates,
            )
        if on_accept is not None and handle is not None:
            on_accept(handle)
        return not (handle is not None and last is handle and bound is not None and updates == {"value": bound})

    return guard


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
            try:
                _number(s.label, s.value)
            except InputError as exc:
                raise InputError(f"{exc} (log10 of the {kind} weight)") from None


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
