"""Exceptions raised by the engine.

Every error a user can cause is a :class:`ValueError` subclass whose message
says what was wrong and what is allowed, so front ends can show it as one line.
"""

from __future__ import annotations

import operator
import reprlib
from enum import Enum

__all__ = [
    "QsidError",
    "ConfigError",
    "SystemDefinitionError",
    "DataOverflowError",
    "MPCFailure",
    "FailureKind",
    "IdentificationError",
    "OutputPathError",
    "short_repr",
    "check_choice",
    "check_int",
    "check_float",
]


class QsidError(ValueError):
    """Base class of every user-facing error of :mod:`qsid_core`."""


class ConfigError(QsidError):
    """A configuration value is out of its allowed range or of the wrong kind."""


class SystemDefinitionError(QsidError):
    """A system definition (A, B, x0, Q, R) is malformed."""


class DataOverflowError(QsidError):
    """Simulated data left the floating-point range (an unstable system)."""


class IdentificationError(QsidError):
    """Identification is impossible from these (quantized) data; sweeps record it per realization."""


class OutputPathError(QsidError):
    """An output path is not a regular file or a new name (a directory, a device, a FIFO, a socket)."""


class FailureKind(str, Enum):
    """Why the MPC of one realisation failed (a ``str``: equal to, and serialised as, its value).

    Like OSQP's ``SolverStatus``, but for the whole closed loop of one identified model.
    """

    #: identification gave no model (singular data)
    IDENT = "ident"
    #: the DARE for the terminal weight has no stabilizing solution
    DARE = "dare"
    #: the QP (with a state or terminal box) has no feasible input sequence
    INFEASIBLE = "infeasible"
    #: the QP solver hit its iteration limit
    MAX_ITER = "max_iter"
    #: any other QP solver failure
    SOLVER = "solver"
    #: the true-system state left the floating-point range (``|x| > 1e12``)
    DIVERGED = "diverged"

    def __str__(self) -> str:  # 'dare', not 'FailureKind.DARE' (also in f-strings on Python < 3.12)
        return self.value

    def __format__(self, spec: str) -> str:
        return format(self.value, spec)


class MPCFailure(QsidError):
    """The MPC could not be built or solved.

    Attributes
    ----------
    kind : FailureKind
        Why (a ``str`` enum: ``exc.kind == "dare"`` holds).
    """

    def __init__(self, kind: FailureKind | str, message: str):
        super().__init__(message)
        self.kind = FailureKind(kind)


_repr = reprlib.Repr()
_repr.maxlevel = 3
_repr.maxlist = _repr.maxtuple = _repr.maxdict = _repr.maxset = 6
_repr.maxstring = _repr.maxother = 40
_repr.maxlong = 24


def short_repr(value: object) -> str:
    """A repr of ``value`` that stays short for huge integers, long texts and deep nesting."""
    try:
        return _repr.repr(value)
    except Exception:  # a failing __repr__ (or one too deep): the type name is enough
        return f"<{type(value).__name__}>"


def check_choice(name: str, value: str, allowed: tuple[str, ...]) -> str:
    """Return ``value`` if it is one of ``allowed``, else raise :class:`ConfigError`."""
    if not isinstance(value, str) or value not in allowed:
        raise ConfigError(f"{name} must be one of {', '.join(repr(a) for a in allowed)}; got {short_repr(value)}")
    return value


def check_int(name: str, value: object, lo: int, hi: int | None = None) -> int:
    """Return ``value`` as int if it is an integer in ``[lo, hi]``, else raise :class:`ConfigError`.

    Accepts Python and numpy integers; rejects bools, floats, texts and arrays.
    """
    if isinstance(value, bool) or type(value).__name__ == "bool_":
        raise ConfigError(f"{name} must be an integer; got {value!r}")
    try:
        v = operator.index(value)  # type: ignore[arg-type]
    except TypeError:
        raise ConfigError(f"{name} must be an integer; got {short_repr(value)}") from None
    if v < lo or (hi is not None and v > hi):
        rng = f">= {lo}" if hi is None else f"between {lo} and {hi}"
        raise ConfigError(f"{name} must be {rng}; got {short_repr(v)}")
    return v


def check_float(
    name: str,
    value: object,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
) -> float:
    """Return ``value`` as a finite float inside the given bounds, else raise :class:`ConfigError`.

    Accepts Python and numpy real numbers; rejects bools, texts, arrays, integers
    too large for a float, nan and inf.
    """
    if isinstance(value, (str, bytes)) or isinstance(value, bool) or type(value).__name__ == "bool_":
        raise ConfigError(f"{name} must be a number; got {short_repr(value)}")
    if getattr(value, "ndim", 0):  # a numpy array of any size
        raise ConfigError(f"{name} must be a single number; got an array")
    try:
        v = float(value)  # type: ignore[arg-type]
    except OverflowError:
        raise ConfigError(f"{name} is too large for a floating-point number; got {short_repr(value)}") from None
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be a number; got {short_repr(value)}") from None
    if v != v or v in (float("inf"), float("-inf")):
        raise ConfigError(f"{name} must be finite; got {short_repr(value)}")
    bad = (lo is not None and (v < lo or (lo_open and v == lo))) or (
        hi is not None and (v > hi or (hi_open and v == hi))
    )
    if bad:
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        lo_s = "-inf" if lo is None else f"{lo:g}"
        hi_s = "inf" if hi is None else f"{hi:g}"
        raise ConfigError(f"{name} must be in {left}{lo_s}, {hi_s}{right}; got {v:g}")
    return v
