"""Which settings of a panel differ from what a lesson set (:func:`lesson_drift`), and the lesson's text as a panel
shows it, marked "modified from the lesson" once they do (:func:`lesson_markdown`).

A lesson's claims are about the panel the lesson sets (:func:`lesson_panel`); any setting its results depend on
that differs is a drift, except b (every lesson asks to move it), what only changes the drawing, and the changes
the lesson's text asks for (:attr:`app.lessons.table.Lesson.moves`).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from app.settings.schema import BY_NAME
from app.settings.values import DISPLAY_ONLY, Values, log_from_weights, resolve_system

from .table import NONE, get_lesson, lesson_names, lesson_values

__all__ = ["lesson_panel", "lesson_drift", "drift_label", "lesson_markdown"]

#: Fields never a drift: b (every lesson's text says "move b to ..."), the lesson itself, what is only drawn
#: differently from the same results (presenter mode, 3-D axes, the bound in 3-D, the quantizer's channel, the
#: compared word lengths) and a preset's matrices (the system names them).
_NOT_A_DRIFT = ("lesson", "a_text", "b_text", *DISPLAY_ONLY)
#: Fields whose empty value means "the system's own" (:class:`~app.settings.values.Values`).
_SYSTEMS_OWN = ("x0", "log_q", "log_r")


@functools.lru_cache(maxsize=64)
def lesson_panel(name: str) -> Values:
    """The panel exactly as opening lesson ``name`` sets it (the dashboard's :func:`app.dashboard.controls.apply_lesson`): its
    values with the system's own x0 and Q/R weights written out (as the panel shows them)."""
    v = lesson_values(name)
    system = resolve_system(v).system
    assert system.Q is not None and system.R is not None and system.x0 is not None  # filled in __post_init__
    x0 = v.x0 or ", ".join(f"{x:g}" for x in system.x0)
    return v.replace(
        x0=x0,
        log_q=tuple(log_from_weights(np.diag(system.Q))),
        log_r=tuple(log_from_weights(np.diag(system.R))),
    )


def _same(a: Any, b: Any) -> bool:
    """Two panel values alike (typed text up to spaces, weights up to rounding)."""
    if isinstance(a, str) and isinstance(b, str):
        return "".join(a.split()) == "".join(b.split())
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and bool(np.allclose(np.asarray(a, float), np.asarray(b, float), atol=1e-6))
    if isinstance(a, float) or isinstance(b, float):
        return bool(np.isclose(float(a), float(b), rtol=1e-9, atol=1e-12))
    return bool(a == b)


@functools.lru_cache(maxsize=256)  # (asked after every change of every tab: a class on one lesson asks alike)
def lesson_drift(name: str, values: Values) -> tuple[str, ...]:
    """The settings in ``values`` that differ from the panel lesson ``name`` set (every setting its results
    depend on: the seeds, the per-channel bits, the Q/R weights ... not b and not what only changes the drawing),
    except the changes its text asks for (:attr:`Lesson.moves`, each followed as a whole)."""
    if name == NONE or name not in lesson_names():
        return ()
    want, own = lesson_panel(name), lesson_values(name)
    drift = [
        k
        for k in want.__dataclass_fields__
        if k not in _NOT_A_DRIFT
        and not _same(getattr(values, k), getattr(want, k))
        # an empty x0 or weights: the system's own, as the lesson's unless it sets them
        and not (k in _SYSTEMS_OWN and not getattr(values, k) and not getattr(own, k))
    ]
    followed = {
        k for move in get_lesson(name).moves if all(_same(getattr(values, k), x) for k, x in move.items()) for k in move
    }
    return tuple(k for k in drift if k not in followed)


def drift_label(field: str) -> str:
    """The panel's name of setting ``field`` (the mark lists them)."""
    s = BY_NAME.get(field)
    return s.label if s is not None else field.replace("_", " ")


def lesson_markdown(name: str, drift: tuple[str, ...] = ()) -> str:
    """What the panel shows under the selector ('' for no lesson); with ``drift`` (the fields changed since the
    lesson set them) a mark first: the text is about the lesson's settings, no longer the panel's."""
    if name == NONE:
        return ""
    les = get_lesson(name)
    stop = "" if les.title[-1] in ".?!" else "."
    mark = ""
    if drift:
        what = ", ".join(drift_label(k) for k in drift)
        mark = f"✎ **Modified from the lesson** ({what}): the text is about the lesson's own settings.\n\n"
    return f"{mark}**{les.title}{stop}** {les.text}"
