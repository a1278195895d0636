"""Time-varying references for the MPC to track, with preview over its horizon.

A reference is given as text or as samples:

* ``step:STATE:AMPLITUDE:TIME`` -- ``r_t = AMPLITUDE`` on state STATE from sample TIME on (0 before);
* ``sine:STATE:AMPLITUDE:PERIOD`` -- ``AMPLITUDE * sin(2 pi t / PERIOD)``;
* ``square:STATE:AMPLITUDE:PERIOD`` -- ``+AMPLITUDE`` for the first half of each period, ``-AMPLITUDE`` after;
* samples, shape (T, n): one row per step (from a CSV file in the CLI); past its last
  row the reference holds the last row.

STATE is a state name (``angle``) or a 1-based index; the other states' references
are 0. TIME and PERIOD are in samples. The MPC at step ``t`` sees ``r_t .. r_{t+N}``
(preview over its horizon ``N``): the letter's cost ``sum (x_k - r_k)'Q(x_k - r_k) + u_k'R u_k``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ConfigError, short_repr

__all__ = ["KINDS", "reference_samples", "parse_reference"]

#: the reference shapes that have a text form
KINDS = ("step", "sine", "square")


def parse_reference(spec: str, state_names: Sequence[str]) -> tuple[str, int, float, float]:
    """``(kind, state index, amplitude, time or period)`` of a text reference (ConfigError if malformed)."""
    form = "reference must look like step:STATE:AMPLITUDE:TIME, sine:STATE:AMPLITUDE:PERIOD or square:STATE:AMPLITUDE:PERIOD"
    parts = str(spec).split(":")
    if len(parts) != 4 or parts[0].strip().lower() not in KINDS:
        raise ConfigError(f"{form}; got {short_repr(spec)}")
    kind, state, amp, when = (p.strip() for p in parts)
    names = list(state_names)
    if state in names:
        idx = names.index(state)
    else:
        try:
            idx = int(state) - 1
        except ValueError:
            raise ConfigError(
                f"reference state must be a state name ({', '.join(names)}) or 1..{len(names)}; got {short_repr(state)}"
            ) from None
        if not 0 <= idx < len(names):
            raise ConfigError(f"reference state must be 1..{len(names)} (or a name: {', '.join(names)}); got {idx + 1}")
    try:
        a, w = float(amp), float(when)
    except ValueError:
        raise ConfigError(f"{form}; amplitude and time/period must be numbers, got {short_repr(spec)}") from None
    if not (np.isfinite(a) and np.isfinite(w)) or abs(a) > 1e12:
        raise ConfigError(f"reference amplitude and time/period must be finite; got {short_repr(spec)}")
    if kind.lower() == "step" and w < 0:
        raise ConfigError(f"step time must be >= 0 samples; got {w:g}")
    if kind.lower() != "step" and w < 2:
        raise ConfigError(f"{kind.lower()} period must be at least 2 samples; got {w:g}")
    return kind.lower(), idx, a, w


def reference_samples(spec: str | ArrayLike, state_names: Sequence[str], length: int) -> np.ndarray:
    """The reference ``r_0 .. r_{length-1}``, shape (length, n).

    Parameters
    ----------
    spec : str or array_like of shape (T, n)
        A text form (module docstring) or samples (held at the last row past T).
    state_names : sequence of str
        The system's states (their number is ``n``).
    length : int
    """
    n = len(state_names)
    t = np.arange(length, dtype=float)
    if isinstance(spec, str):
        kind, idx, a, w = parse_reference(spec, state_names)
        r = np.zeros((length, n))
        if kind == "step":
            r[:, idx] = np.where(t >= w, a, 0.0)
        elif kind == "sine":
            r[:, idx] = a * np.sin(2 * np.pi * t / w)
        else:
            r[:, idx] = np.where((t % w) < w / 2, a, -a)
        return r
    arr = np.asarray(spec, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != n or arr.shape[0] < 1:
        raise ConfigError(
            f"reference samples must have one row per step and {n} columns (one per state); got shape {arr.shape}"
        )
    if not np.all(np.isfinite(arr)) or np.abs(arr).max() > 1e12:
        raise ConfigError("reference samples must be finite numbers (at most 1e12 in size)")
    idx = np.minimum(np.arange(length), arr.shape[0] - 1)
    out: np.ndarray = arr[idx]
    return out
