"""Text typed in the panel -> numbers (pure functions, no server).

Matrices, vectors, fixed quantizer ranges and state boxes as a person types them, read strictly and
explained in plain words (:class:`~app.settings.check.InputError`); and the log10 weight sliders <-> weights.
:mod:`app.settings.config` builds the engine configuration from them.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from app.settings.check import InputError
from qsid_core import QsidError, SystemDefinitionError
from qsid_core.validate import parse_matrix

__all__ = [
    "LOG_MIN",
    "LOG_MAX",
    "MIN_ENTRY",
    "FIXED_RANGE_MAX",
    "matrix_text",
    "panel_matrix",
    "parse_vector",
    "fixed_range",
    "state_box",
    "weights_from_log",
    "log_from_weights",
    "format_weights",
]

#: Range of the log10 weight sliders.
LOG_MIN, LOG_MAX = -3.0, 3.0
#: Largest |lo|, |hi| of a typed fixed quantizer range (beyond it eps overflows or loses all precision).
FIXED_RANGE_MAX = 1e12


def _fmt(x: float) -> str:
    return f"{x:.6g}"


def matrix_text(M: np.ndarray) -> str:
    """A matrix as the panel shows it: one row per line, entries separated by spaces."""
    return "\n".join(" ".join(_fmt(float(v)) for v in row) for row in np.atleast_2d(M))


#: Smallest magnitude of a nonzero typed entry: products of two stay normal floating-point numbers.
MIN_ENTRY = 1e-150


def panel_matrix(text: str, name: str) -> np.ndarray:
    """A matrix typed in the panel (see :func:`qsid_core.validate.parse_matrix`), stricter than a file:
    plain ASCII only (no other scripts' digits read as numbers) and no nonzero entry below
    :data:`MIN_ENTRY` in magnitude (subnormal numbers break the Riccati and least-squares solvers).

    Raises
    ------
    QsidError
        Naming the matrix and the entry.
    """
    if isinstance(text, str) and not text.isascii():
        bad = next(ch for ch in text if not ch.isascii())
        raise SystemDefinitionError(f"{name}: {bad!r} is not allowed; type numbers with the digits 0-9 (plain ASCII)")
    M = parse_matrix(text, name)
    tiny = (M != 0) & (np.abs(M) < MIN_ENTRY)
    if np.any(tiny):
        raise SystemDefinitionError(
            f"{name}: the entry {M[tiny][0]:g} is too close to zero for the numerics; "
            f"write 0 or a magnitude of at least {MIN_ENTRY:g}"
        )
    return M


def parse_vector(text: str, name: str, k: int, what: str = "") -> tuple[float, ...] | None:
    """``k`` numbers typed as ``"1, 0, 0"`` (spaces or commas); empty text -> None (use the default)."""
    s = (text or "").strip()
    if not s:
        return None
    return _numbers(s, name, k, what)


def _numbers(s: str, name: str, k: int, what: str) -> tuple[float, ...]:
    """The ``k`` numbers of the non-empty stripped text ``s`` (see :func:`parse_vector`)."""
    try:
        if s.startswith("[") and not s[1:].lstrip().startswith("["):  # a flat JSON list: one row
            s = f"[{s}]"
        arr = panel_matrix(s.replace(";", " ").replace("\n", " "), name).reshape(-1)
    except QsidError as exc:
        raise InputError(str(exc)) from None
    if arr.size != k:
        raise InputError(f"{name} needs {k} numbers{what}; got {arr.size}")
    return tuple(float(x) for x in arr)


def fixed_range(text: str, n: int, m: int) -> tuple:
    """A fixed quantizer range typed in the panel: one ``lo, hi`` pair for every channel, or ``n + m`` rows
    ``lo hi`` (states then inputs); returns one ``(lo, hi)`` pair per row given."""
    s = (text or "").strip()
    if not s:
        raise InputError("fixed range: type 'lo, hi' (one range for every channel) or one 'lo hi' row per channel")
    try:
        M = parse_matrix(s, "fixed range")
    except QsidError as exc:
        raise InputError(str(exc)) from None
    if M.size == 2:
        pairs = M.reshape(1, 2)
    elif M.shape == (n + m, 2):
        pairs = M
    else:
        raise InputError(
            f"fixed range: give one 'lo, hi' pair, or {n + m} rows 'lo hi' (states then inputs); got shape {M.shape}"
        )
    if not np.all(np.isfinite(pairs)) or np.abs(pairs).max() > FIXED_RANGE_MAX:
        raise InputError(f"fixed range: every number must lie between -{FIXED_RANGE_MAX:g} and {FIXED_RANGE_MAX:g}")
    if np.any(pairs[:, 1] <= pairs[:, 0]):
        raise InputError("fixed range: every range needs lo < hi")
    if np.any(pairs[:, 1] - pairs[:, 0] < 1e-9 * np.maximum(1.0, np.abs(pairs).max(axis=1))):
        raise InputError(
            "fixed range: a range this narrow leaves no room for 2^b cells "
            "(hi - lo must be at least 1e-9 × max(1, |lo|, |hi|))"
        )
    return tuple(map(tuple, pairs.tolist()))


def state_box(text: str, n: int, names: str, what: str = "x_max") -> tuple[float, ...] | None:
    """A state box typed in the panel: one bound for every state or one per state ("" = no box)."""
    s = (text or "").strip()
    if not s:
        return None
    k = len(s.replace(",", " ").replace(";", " ").split())
    box = _numbers(s, what, 1 if k == 1 else n, f" (one for every state, or one per state: {names})")
    if not all(np.isfinite(x) and x > 0 for x in box):
        raise InputError(f"{what}: every bound must be a positive number; got {s!r}")
    return box if len(box) == n else box * n


def weights_from_log(logs: Iterable[float]) -> tuple[float, ...]:
    """Slider positions (log10 of the weight) -> weights, rounded to 4 significant digits."""
    return tuple(float(f"{10.0 ** float(x):.4g}") for x in logs)


def log_from_weights(diag: Iterable[float]) -> tuple[float, ...]:
    """Weights -> slider positions (log10, clipped to the slider range, 0 weights at the bottom)."""
    out = []
    for w in np.asarray(diag, dtype=float).reshape(-1):
        x = np.log10(w) if w > 0 else LOG_MIN
        out.append(round(float(np.clip(x, LOG_MIN, LOG_MAX)), 2))
    return tuple(out)


def format_weights(name: str, diag: Iterable[float]) -> str:
    """A weight diagonal as the panel prints it, e.g. ``Q = diag(1, 0.1)``."""
    return f"{name} = diag({', '.join(f'{w:.3g}' for w in diag)})"
