"""Input checks shared by every engine entry point.

Each helper either returns a clean value or raises a :class:`~qsid_core.errors.QsidError`
subclass whose message names the field, what is wrong and what is allowed. They
never recurse (deeply nested lists are rejected by depth, not by a RecursionError),
never convert huge integers blindly (``OverflowError``) and keep quoted values short.
"""

from __future__ import annotations

import datetime as _dt
import json
import numbers
import stat
from collections.abc import Mapping
from typing import Any, SupportsInt, cast

import numpy as np

from .errors import ConfigError, SystemDefinitionError, short_repr

__all__ = [
    "MAX_MAGNITUDE",
    "MAX_ENTRIES",
    "as_float_array",
    "check_bool",
    "check_text",
    "check_quantizer_range",
    "checked_signal",
    "as_matrix",
    "weight_matrix",
    "parse_matrix",
    "special_file_kind",
]

#: Largest magnitude accepted for a model entry, weight, bound or state (squared costs must not overflow).
MAX_MAGNITUDE = 1e12
#: Largest number of entries accepted in one array-valued setting.
MAX_ENTRIES = 1_000_000


#: What a path that is not a regular file is, in words (the first test its mode passes).
_FILE_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def special_file_kind(mode: int) -> str | None:
    """``mode`` (``os.stat(...).st_mode``) in words when it is a directory, pipe, device or socket, else None."""
    return next((word for test, word in _FILE_KINDS if test(mode)), None)


def _kind(value: Any) -> str:
    """Plain words for what a bad entry is."""
    if isinstance(value, (bool, np.bool_)):
        return f"true/false ({value})"
    if value is None:
        return "empty (null/None)"
    if isinstance(value, str):
        return f"text {short_repr(value)}"
    if isinstance(value, Mapping):
        return "a table/object (key: value pairs)"
    if isinstance(value, (_dt.date, _dt.time)):
        return f"a date/time ({value})"
    if isinstance(value, complex):
        return f"a complex number {value}"
    return f"{short_repr(value)} ({type(value).__name__})"


def _where(path: tuple[int, ...]) -> str:
    """Where a bad value is, counted from 1 as a person reads it: ``"entry 3 is"`` (a list),
    ``"row 2, column 1 is"`` (a matrix), ``"entry (1, 2, 3) is"`` (deeper), ``"it is"`` (a single value)."""
    if not path:
        return "it is"
    if len(path) == 1:
        return f"entry {path[0] + 1} is"
    if len(path) == 2:
        return f"row {path[0] + 1}, column {path[1] + 1} is"
    return f"entry ({', '.join(str(i + 1) for i in path)}) is"


def _walk(name: str, value: Any, ndim_max: int, error: type, what: str | None = None) -> None:
    """Check the nesting and the leaf types of a list-of-lists without recursion."""
    what = what or {0: "a number", 1: "a list of numbers", 2: "a matrix of numbers (a list of rows)"}.get(
        ndim_max, f"an array of numbers with at most {ndim_max} dimensions"
    )
    stack: list[tuple[Any, tuple[int, ...]]] = [(value, ())]
    count = 0
    while stack:
        v, path = stack.pop()
        if isinstance(v, (list, tuple)):
            if len(path) >= ndim_max:
                raise error(f"{name} must be {what}; it is nested deeper than {ndim_max} level(s) of brackets")
            stack.extend((x, path + (i,)) for i, x in enumerate(v))
            continue
        if isinstance(v, np.ndarray) and v.dtype.kind in "iuf" and v.ndim + len(path) <= ndim_max:
            count += v.size
        elif isinstance(v, (bool, np.bool_)) or not isinstance(v, (numbers.Real, np.integer, np.floating)):
            raise error(f"{name} must be {what}; {_where(path)} {_kind(v)}")
        else:
            try:
                float(v)
            except OverflowError:
                digits = int(int(cast(SupportsInt, v)).bit_length() * 0.30103) + 1  # an int, or a Fraction
                raise error(
                    f"{name}: {_where(path)} an integer with about {digits} digits, too large "
                    "for a floating-point number"
                ) from None
            count += 1
        if count > MAX_ENTRIES:
            raise error(f"{name} has more than {MAX_ENTRIES} entries")


def as_float_array(
    name: str,
    value: Any,
    *,
    ndim_max: int = 2,
    error: type = ConfigError,
    max_abs: float | None = MAX_MAGNITUDE,
    allow_empty: bool = False,
    what: str | None = None,
) -> np.ndarray:
    """``value`` as a finite float array with at most ``ndim_max`` dimensions.

    Accepts numbers, (nested) lists/tuples of numbers and numeric numpy arrays.
    Rejects, with the offending entry named: text, true/false, null, tables/dicts,
    dates, complex numbers, nesting deeper than ``ndim_max``, ragged rows,
    integers too large for a float, nan/inf, entries above ``max_abs`` in
    magnitude (None: no limit) and, unless ``allow_empty``, empty input.
    ``what`` says in words what is expected (default from ``ndim_max``).
    """
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "iuf":
            if value.dtype.kind != "O":
                raise error(f"{name} must hold numbers; got an array of {value.dtype} values")
            value = value.tolist()
        elif value.ndim > ndim_max:
            raise error(f"{name} must have at most {ndim_max} dimension(s); got {value.ndim}")
    if not isinstance(value, np.ndarray):
        _walk(name, value, ndim_max, error, what)
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise error(f"{name}: every row must have the same number of entries; got {short_repr(value)}") from None
    if arr.size == 0 and not allow_empty:
        raise error(f"{name} must not be empty")
    bad = ~np.isfinite(arr)
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        v = arr[idx] if idx else arr.item()
        why = " (a number beyond ±1.8e308 reads as inf)" if np.isinf(v) else ""
        raise error(f"{name} must contain only finite numbers (no nan or inf); {_where(idx)} {v}{why}")
    if max_abs is not None and arr.size and np.abs(arr).max() > max_abs:
        idx = tuple(int(i) for i in np.argwhere(np.abs(arr) > max_abs)[0])
        raise error(
            f"{name}: entries must be at most {max_abs:g} in magnitude; {_where(idx)} "
            f"{(arr[idx] if idx else arr.item()):g}"
        )
    return arr


def check_bool(name: str, value: Any) -> bool:
    """``value`` if it is True or False (also numpy's), else :class:`ConfigError`."""
    if not isinstance(value, (bool, np.bool_)):
        raise ConfigError(f"{name} must be True or False; got {short_repr(value)}")
    return bool(value)


def check_text(name: str, value: Any, error: type = ConfigError, max_len: int = 1000) -> str:
    """``value`` if it is a text string of at most ``max_len`` characters."""
    if not isinstance(value, str):
        raise error(f"{name} must be text; got {short_repr(value)} ({type(value).__name__})")
    if len(value) > max_len:
        raise error(f"{name} must be at most {max_len} characters; got {len(value)}")
    return value


#: Largest word length the range check must support (kept equal to quantize.MAX_BITS).
_MAX_BITS = 32


def check_quantizer_range(name: str, lo: np.ndarray, hi: np.ndarray) -> None:
    """Raise :class:`ConfigError` unless every ``[lo, hi]`` gives a finite, positive cell width at every b.

    Needs ``lo < hi``, both finite, ``hi - lo`` finite (``-1e308, 1e308`` overflows)
    and ``(hi - lo) / 2**32`` a normal float (``0, 5e-324`` gives eps = 0).
    """
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise ConfigError(f"{name}: lo and hi must be finite numbers")
    if np.any(hi <= lo):
        raise ConfigError(
            f"{name}: every range needs hi > lo; got lo = {short_repr(lo.tolist())}, hi = {short_repr(hi.tolist())}"
        )
    with np.errstate(over="ignore"):
        width = hi - lo
    if not np.all(np.isfinite(width)):
        raise ConfigError(
            f"{name}: hi - lo overflows the floating-point range; use |lo|, |hi| below 8e307 "
            f"(a range of {np.max(width):g} would make the cell width eps infinite)"
        )
    tiny = np.finfo(float).tiny * 2.0**_MAX_BITS
    if np.any(width < tiny):
        raise ConfigError(
            f"{name}: hi - lo = {np.min(width):g} is too small; it must be at least {tiny:.3g} "
            f"so that the cell width eps = (hi - lo) / 2**b stays a positive number"
        )


def checked_signal(x: Any, lo: Any, hi: Any, unit_dither: Any, rng: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The arguments of :func:`qsid_core.quantization.quantize.quantize` checked: ``(x, lo, hi)`` as float arrays.

    ``x`` finite numbers of any shape; ``lo``/``hi`` broadcasting against it with a
    usable range (see :func:`check_quantizer_range`); ``unit_dither`` finite with
    the shape of ``x``; ``rng`` a numpy Generator or None.
    """
    xa = as_float_array("x (signal)", x, ndim_max=32, max_abs=None, allow_empty=True)
    lo_a = as_float_array("lo", lo, ndim_max=1, max_abs=None)
    hi_a = as_float_array("hi", hi, ndim_max=1, max_abs=None)
    try:
        if np.broadcast_shapes(xa.shape, lo_a.shape, hi_a.shape) != xa.shape:
            raise ValueError
    except ValueError:
        raise ConfigError(
            f"lo and hi must be one number or one per channel (last axis of x, {xa.shape[-1:]}); "
            f"got shapes {lo_a.shape} and {hi_a.shape}"
        ) from None
    check_quantizer_range("quantizer range", lo_a, hi_a)
    if unit_dither is not None:
        ud = as_float_array("unit_dither", unit_dither, ndim_max=32, max_abs=None, allow_empty=True)
        if ud.shape != xa.shape:
            raise ConfigError(f"unit_dither must have the shape of x {xa.shape}; got {ud.shape}")
    if rng is not None and not isinstance(rng, np.random.Generator):
        raise ConfigError(
            f"rng must be a numpy Generator (numpy.random.default_rng(seed)) or None; got {type(rng).__name__}"
        )
    return xa, lo_a, hi_a


def as_matrix(
    name: str, value: Any, shape: tuple[int | None, int | None], max_abs: float | None = MAX_MAGNITUDE
) -> np.ndarray:
    """``value`` as a 2-D finite float matrix of ``shape`` (None: any size), else :class:`SystemDefinitionError`."""
    arr = as_float_array(name, value, ndim_max=2, error=SystemDefinitionError, max_abs=max_abs)
    if arr.ndim == 1 and shape[1] == 1:
        arr = arr.reshape(-1, 1)
    if arr.ndim != 2:
        raise SystemDefinitionError(f"{name} must be a 2-D matrix (list of rows); got {arr.ndim}-D")
    for axis, want in enumerate(shape):
        if want is not None and arr.shape[axis] != want:
            raise SystemDefinitionError(
                f"{name} must have shape {tuple(s if s is not None else '*' for s in shape)}; got {arr.shape}"
            )
    return arr


def weight_matrix(name: str, value: Any, k: int) -> np.ndarray:
    """A weight matrix: a k x k matrix, or a length-k vector meaning its diagonal."""
    arr = as_float_array(
        name,
        value,
        ndim_max=2,
        error=SystemDefinitionError,
        what=f"a {k} x {k} matrix of numbers (a list of rows) or a list of {k} diagonal entries",
    )
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim == 1:
        if arr.shape[0] != k:
            raise SystemDefinitionError(f"{name} as a diagonal must have {k} entries; got {arr.shape[0]}")
        arr = np.diag(arr)
    arr = as_matrix(name, arr, (k, k))
    if not np.allclose(arr, arr.T, atol=1e-12):
        raise SystemDefinitionError(f"{name} must be symmetric")
    return arr


def parse_matrix(text: str, name: str = "matrix") -> np.ndarray:
    """Parse a matrix typed by a person: rows separated by ``;`` or newlines, entries by spaces or commas.

    Also accepts a JSON list of lists. Raises :class:`SystemDefinitionError` with the
    offending row when the rows have different lengths or an entry is not a number.
    """
    s = check_text(name, text, SystemDefinitionError, max_len=1_000_000).strip()
    if not s:
        raise SystemDefinitionError(f"{name} is empty")
    if s.startswith("["):
        try:
            return as_matrix(name, json.loads(s), (None, None), max_abs=None)
        except json.JSONDecodeError as exc:
            raise SystemDefinitionError(f"{name}: not valid JSON ({exc.msg})") from None
        except RecursionError:
            raise SystemDefinitionError(f"{name}: brackets nested too deeply (give a list of rows)") from None
    rows = [r for r in s.replace(";", "\n").splitlines() if r.strip()]
    out = []
    for i, row in enumerate(rows, 1):
        parts = row.replace(",", " ").split()
        try:
            out.append([float(v) for v in parts])
        except ValueError:
            raise SystemDefinitionError(
                f"{name} row {i}: {short_repr(row.strip())} has an entry that is not a number"
            ) from None
    widths = {len(r) for r in out}
    if len(widths) != 1:
        raise SystemDefinitionError(f"{name}: rows have different lengths {short_repr([len(r) for r in out])}")
    return as_matrix(name, out, (None, None), max_abs=None)
