"""Checks of the engine's composite arguments (which need the config classes themselves), and the parsers of
the word lengths and the noise (:func:`parse_bits`, :func:`parse_input_bits`, :func:`parse_state_bits`,
:func:`parse_noise`), which :mod:`~qsid_core.studies.config` re-exports.

Kept apart from :mod:`qsid_core.validate` (imported by every module) so that there is no import cycle:
this module imports :mod:`~qsid_core.control.mpc` and :mod:`~qsid_core.plant.systems` and is imported by the sweep modules.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

import numpy as np

from ..control.mpc import MPCConfig
from ..errors import ConfigError, check_float, check_int, short_repr
from ..plant.lti import LTISystem
from ..quantization.quantize import MAX_BITS
from ..validate import MAX_MAGNITUDE

#: The inputs' word length as :func:`parse_input_bits` gives it: None (the swept b), "exact", one for all inputs,
#: or one entry per input.
InputBits = None | str | int | tuple[int | str, ...]

__all__ = [
    "InputBits",
    "check_run_args",
    "check_sweep_parts",
    "parse_bits",
    "parse_input_bits",
    "parse_noise",
    "parse_state_bits",
]


def check_sweep_parts(system: Any, mpc: Any, rho: Any) -> None:
    """Types of :class:`~qsid_core.studies.experiment.SweepConfig`'s ``system`` and ``mpc``, and the range of ``rho``."""
    if not isinstance(system, (str, Path, LTISystem)):
        raise ConfigError(
            f"system must be a preset name, a path to a .toml/.json file or an LTISystem; "
            f"got {short_repr(system)} ({type(system).__name__})"
        )
    if mpc is not None and not isinstance(mpc, MPCConfig):
        raise ConfigError(
            f"mpc must be an MPCConfig, or None to skip the closed loops; got {short_repr(mpc)} ({type(mpc).__name__})"
        )
    if rho is not None:
        check_float("rho", rho, 0.0, MAX_MAGNITUDE, lo_open=True)


def check_run_args(config: Any, config_type: type, executor: Any, progress: Any) -> None:
    """Arguments of :func:`~qsid_core.studies.sweep.run_sweep` / :class:`~qsid_core.studies.experiment.Experiment`.

    ``config_type`` is :class:`~qsid_core.studies.experiment.SweepConfig` (passed in: that module imports this one).
    """
    if not isinstance(config, config_type):
        raise ConfigError(f"config must be a SweepConfig; got {type(config).__name__}")
    if executor is not None and not isinstance(executor, Executor) and not callable(getattr(executor, "submit", None)):
        raise ConfigError(f"executor must be a concurrent.futures.Executor (or None); got {type(executor).__name__}")
    if progress is not None and not callable(progress):
        raise ConfigError(
            f"progress must be a function progress(done, total, stage) or None; got {type(progress).__name__}"
        )


def parse_bits(spec: str | int | Sequence[int] | range) -> tuple[int, ...]:
    """Word lengths from ``"2:12"`` (inclusive), ``"2:12:2"``, ``"2,4,6"``, ``"8"``, an int, or a sequence of ints.

    Raises
    ------
    ConfigError
        If the text is not of one of those forms or a b is outside 1..32.
    """
    if isinstance(spec, (list, tuple, range, np.ndarray)):
        if len(spec) > 1000 if not isinstance(spec, range) else not (0 <= spec.start and spec.stop <= 1000):
            raise ConfigError(f"bits: give at most a few dozen word lengths between 1 and {MAX_BITS}")
        vals = [check_int("bits", int(v) if isinstance(v, np.integer) else v, 1, MAX_BITS) for v in spec]
    elif isinstance(spec, int) and not isinstance(spec, bool):
        vals = [check_int("bits", spec, 1, MAX_BITS)]
    else:
        form = "bits must look like '2:12' (inclusive), '2:12:2' (with a step), '2,4,6' or '8'"
        if not isinstance(spec, str) or len(spec) > 200:
            raise ConfigError(f"{form}; got {short_repr(spec)}")
        s = spec.strip()
        try:
            if ":" in s:
                parts = [int(v) for v in s.split(":")]
                if len(parts) not in (2, 3):
                    raise ValueError
                lo, hi = parts[0], parts[1]
                step = parts[2] if len(parts) == 3 else 1
            else:
                vals = [int(v) for v in s.split(",") if v.strip()]
        except ValueError:
            raise ConfigError(f"{form}; got {short_repr(s)}") from None
        if ":" in s:
            if step < 1:
                raise ConfigError(f"bits step must be >= 1; got {short_repr(step)} in {short_repr(s)}")
            if hi < lo:
                raise ConfigError(
                    f"bits range {short_repr(s)} is empty (end {short_repr(hi)} < start {short_repr(lo)})"
                )
            check_int("bits range start", lo, 1, MAX_BITS)  # bounds before building the range
            check_int("bits range end", hi, 1, MAX_BITS)
            vals = list(range(lo, hi + 1, step))
        if not vals:
            raise ConfigError(f"{form}; got {short_repr(s)}")
        vals = [check_int("bits", v, 1, MAX_BITS) for v in vals]
    out = tuple(sorted(set(vals)))
    if not out:
        raise ConfigError("bits: give at least one word length")
    return out


def parse_input_bits(spec: object) -> InputBits:
    """Word length of the inputs: None or ``"same"`` (as the states), ``"exact"``, one int, or one per input.

    Accepts ``12``, ``"12"``, ``"exact"``, ``"8,12"``, ``"exact,8"`` or a sequence of ints / ``"exact"``.

    Raises
    ------
    ConfigError
        For anything else, or a word length outside 1..32.
    """
    form = "input bits must be 'same', 'exact', a word length 1..32, or one per input like '8,12' or 'exact,8'"
    if spec is None:
        return None
    if isinstance(spec, str):
        s = spec.strip().lower()
        if s in ("", "same"):
            return None
        if s == "exact":
            return "exact"
        items = [v.strip() for v in s.split(",")]
        if len(s) > 200 or not all(items):
            raise ConfigError(f"{form}; got {short_repr(spec)}")
        if len(items) == 1:
            try:
                return check_int("input bits", int(items[0]), 1, MAX_BITS)
            except ValueError:
                raise ConfigError(f"{form}; got {short_repr(spec)}") from None
        spec = items
    if isinstance(spec, (int, np.integer)) and not isinstance(spec, bool):
        return check_int("input bits", int(spec), 1, MAX_BITS)
    if isinstance(spec, (list, tuple)) and 0 < len(spec) <= 1000:
        out: list[int | str] = []
        for v in spec:
            if isinstance(v, str) and v.strip().lower() in ("exact", "b", "same"):
                out.append("exact" if v.strip().lower() == "exact" else "b")
                continue
            try:
                out.append(check_int("input bits", int(v) if isinstance(v, (str, np.integer)) else v, 1, MAX_BITS))
            except (TypeError, ValueError):
                raise ConfigError(f"{form}; got {short_repr(v)} in {short_repr(spec)}") from None
        return tuple(out)
    raise ConfigError(f"{form}; got {short_repr(spec)}")


def parse_state_bits(spec: object) -> tuple[int | str, ...] | None:
    """Word length of each state: None or ``""``/``"b"`` (every state has the swept b), else one entry for all
    states or one per state.

    Entries: ``"b"`` (the swept word length), a word length 1..32, or ``"exact"``; e.g. ``"b,b,12,exact"``.

    Raises
    ------
    ConfigError
        For anything else.
    """
    form = "state bits must be one entry per state, each 'b' (the swept b), a word length 1..32 or 'exact'"
    if spec is None or (isinstance(spec, str) and spec.strip().lower() in ("", "b", "same")):
        return None
    if isinstance(spec, str):
        if len(spec) > 2000:
            raise ConfigError(f"{form}; got {short_repr(spec)}")
        spec = [v.strip() for v in spec.split(",")]
    if not isinstance(spec, (list, tuple)) or not spec or any(isinstance(v, str) and not v for v in spec):
        raise ConfigError(f"{form}; got {short_repr(spec)}")
    try:
        out = parse_input_bits(list(spec) if len(spec) > 1 else [spec[0], "b"])
    except ConfigError:
        raise ConfigError(f"{form}; got {short_repr(spec)}") from None
    assert isinstance(out, tuple)  # a list of two or more entries is always read as one entry per channel
    return out if len(spec) > 1 else out[:1]


def parse_noise(spec: object) -> tuple[float, ...]:
    """Sensor noise standard deviations: one for every state, or one per state (``0.01`` or ``"0.01,0.02"``).

    Raises
    ------
    ConfigError
        If a value is negative or not a finite number.
    """
    if isinstance(spec, str):
        try:
            spec = [float(v) for v in spec.split(",") if v.strip()] if len(spec) <= 2000 else None
        except ValueError:
            spec = None
        if not spec:
            raise ConfigError(
                "noise must be one standard deviation >= 0 or one per state, like '0.01' or '0.01,0,0.02'"
            )
    vals = list(spec) if isinstance(spec, (list, tuple, np.ndarray)) else [spec]
    if not 0 < len(vals) <= 1000:
        raise ConfigError("noise must be one standard deviation >= 0 or one per state")
    return tuple(check_float("noise", v, 0.0, 1e12) for v in vals)
