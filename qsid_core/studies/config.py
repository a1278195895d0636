"""Sweep configuration: :class:`SweepConfig` (everything a sweep depends on) and :func:`parse_bits`.

:meth:`SweepConfig.letter` gives the letter's own settings (Section V); the plain
defaults differ from them only in the quantizer's guard band (on by default, see
:mod:`qsid_core.quantization.quantize`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

from ..control.mpc import MPCConfig
from ..errors import ConfigError, check_choice, check_float, check_int, short_repr
from ..identification.identify import ESTIMATORS
from ..plant.lti import LTISystem
from ..quantization.quantize import LETTER_QUANTIZER, MAX_BITS, QuantizerSpec
from ..validate import check_bool
from .config_checks import check_sweep_parts

#: The inputs' word length as :func:`parse_input_bits` gives it: None (the swept b), "exact", one for all inputs,
#: or one entry per input.
InputBits = None | str | int | tuple[int | str, ...]

__all__ = ["SweepConfig", "parse_bits", "parse_input_bits", "parse_noise", "parse_state_bits"]


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


#: Fields written as tables of their own by :meth:`SweepConfig.to_dict` (every other field as it is).
_NESTED = {"system", "quantizer", "mpc"}
#: :meth:`SweepConfig.to_dict`'s keys of the quantizer -> QuantizerSpec fields.
_QUANT_KEYS = {"dither": "dither", "range": "range_mode", "guard": "guard", "fixed_range": "fixed_range"}


@dataclass(frozen=True)
class SweepConfig:
    """Everything a sweep depends on.

    Parameters
    ----------
    system : str or LTISystem
        Preset name (``"dc-motor"``, ``"boeing747"``), path to a .toml/.json file, or a system.
    bits : tuple of int
        Word lengths to sweep (1..32); strings like ``"2:12"`` are parsed.
    realizations : int, 1..10000
        Dither realizations per b (default 50).
    trajectories, steps : int
        Data size (defaults 200 x 1000, the letter's).
    input_amplitude : float, > 0
        Training inputs are u ~ U[-A, A] (input units; default 1, the letter's).
    state_amplitude : float, > 0
        Initial states of the training runs are x0 ~ U[-a, a]^n (state units; default 1, the letter's).
    data_seed, dither_seed : int
        Seeds of the data and of the dither streams.
    quantizer : QuantizerSpec
        Dither, range mode, guard band (on by default) and fixed range.
    estimator : {"ls", "bcls"}
    mpc : MPCConfig or None
        None skips the closed loops (identification and theory only).
    theta, rho : float
        Parameters of the ultimate bound (see :func:`qsid_core.control.bound.ultimate_bound`);
        ``rho=None`` picks the documented default.
    input_bits : None, "exact", int or tuple
        Word length of the inputs (:func:`parse_input_bits`): None = the swept b,
        ``"exact"`` = inputs recorded without quantization, one int for all
        inputs or one entry per input; the swept ``bits`` are the states'.
    state_bits : None or tuple
        Word length of each state (:func:`parse_state_bits`): None = every state has
        the swept b; else one entry per state, ``"b"`` (swept), an int or ``"exact"``.
    noise : float or tuple of float, >= 0
        Standard deviation of Gaussian sensor noise added to the recorded states
        before quantization (one for all states or one per state; default 0).
        Drawn from its own stream seeded by ``data_seed``.
    noise_known : bool
        BCLS (and nothing else) adds the noise variance ``sigma**2`` to ``D``;
        without it BCLS corrects only the quantization noise it knows of.
    """

    system: str | LTISystem = "dc-motor"
    bits: tuple[int, ...] = tuple(range(1, 17))
    realizations: int = 50
    trajectories: int = 200
    steps: int = 1000
    data_seed: int = 0
    dither_seed: int = 1
    quantizer: QuantizerSpec = field(default_factory=QuantizerSpec)
    estimator: str = "ls"
    mpc: MPCConfig | None = field(default_factory=MPCConfig)
    theta: float = 0.5
    rho: float | None = None
    input_amplitude: float = 1.0
    input_bits: InputBits = None
    noise: tuple[float, ...] = (0.0,)
    state_bits: tuple[int | str, ...] | None = None
    noise_known: bool = False
    state_amplitude: float = 1.0

    def to_dict(self, system: LTISystem | None = None) -> dict[str, Any]:
        """Every setting as plain JSON data; :meth:`from_dict` reads it back to an equal config.

        ``system`` (the resolved :class:`LTISystem`, default ``get_system(self.system)``) is
        written in full (A, B, x0, Q, R, dt) under ``system_definition``; ``mpc_settings`` holds
        every :class:`MPCConfig` field as given (None = its documented default).
        """
        from ..plant.systems import get_system

        q = self.quantizer
        sysm = system if system is not None else get_system(self.system)
        plain = {
            f.name: (list(v) if isinstance(v, tuple) else v)
            for f in fields(self)
            if f.name not in _NESTED
            for v in [getattr(self, f.name)]
        }
        return {
            **plain,
            "dither": q.dither,
            "range": q.range_mode,
            "guard": q.guard,
            "fixed_range": None if q.fixed_range is None else [list(p) for p in q.fixed_range],
            "system_definition": sysm.to_dict(),
            "mpc_settings": None
            if self.mpc is None
            else {
                f.name: (list(v) if isinstance(v, tuple) else v)
                for f in fields(self.mpc)
                for v in [getattr(self.mpc, f.name)]
            },
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> SweepConfig:
        """A config from :meth:`to_dict`'s data, a whole JSON result (its ``config``) or a TOML table.

        Keys are :meth:`to_dict`'s; ``system`` may be a preset name or file path, or a table with
        A, B [, x0, Q, R, dt] (``system_definition`` wins when both are present); ``mpc`` (or
        ``mpc_settings``) is a table of :class:`MPCConfig` fields, or null/false for no MPC.

        Raises
        ------
        ConfigError
            For unknown keys (listed with the allowed ones) or bad values.
        """
        if not isinstance(d, Mapping):
            raise ConfigError("a sweep configuration must be a table/object of settings")
        if isinstance(d.get("config"), Mapping):  # a whole result
            d = d["config"]
        d = dict(d)
        allowed = (
            {f.name for f in fields(cls)} - _NESTED
            | set(_QUANT_KEYS)
            | {
                "system",
                "system_definition",
                "mpc",
                "mpc_settings",
            }
        )
        unknown = sorted(set(d) - allowed)
        if unknown:
            raise ConfigError(f"unknown setting(s) {unknown}; allowed: {', '.join(sorted(allowed))}")
        from ..plant.systems import get_system, system_from_dict

        sysd = d.pop("system_definition", None)
        sysv = d.pop("system", None)
        if sysd is None and isinstance(sysv, Mapping):
            sysd = sysv
        system = (
            system_from_dict(sysd, str(sysd.get("name", "custom")))
            if sysd is not None
            else get_system(sysv if sysv is not None else cls.system)
        )
        mset = d.pop("mpc_settings", None) if "mpc_settings" in d else d.get("mpc", {})
        d.pop("mpc", None)
        if mset is None or mset is False:
            mpc = None
        elif isinstance(mset, Mapping):
            names = {f.name for f in fields(MPCConfig)}
            bad = sorted(set(mset) - names)
            if bad:
                raise ConfigError(f"unknown MPC setting(s) {bad}; allowed: {', '.join(sorted(names))}")
            given: dict[str, Any] = {k: (tuple(v) if isinstance(v, list) else v) for k, v in mset.items()}
            mpc = MPCConfig(**given)
        else:
            raise ConfigError("mpc must be a table of MPC settings, or null/false for no MPC")
        qargs = {_QUANT_KEYS[k]: d.pop(k) for k in list(d) if k in _QUANT_KEYS}
        if isinstance(qargs.get("fixed_range"), list):
            qargs["fixed_range"] = tuple(tuple(p) if isinstance(p, list) else p for p in qargs["fixed_range"])
        for k, v in list(d.items()):
            if isinstance(v, list):  # JSON lists back to the tuples the fields hold
                d[k] = tuple(v)
        return cls(system=system, quantizer=QuantizerSpec(**qargs), mpc=mpc, **d)

    @classmethod
    def letter(cls, system: str | LTISystem = "dc-motor", **overrides: Any) -> SweepConfig:
        """The letter's settings (Section V), which ``qsid reproduce`` uses.

        b = 1..16, 50 dither realizations, 200 runs x 1000 steps, x0 ~ U[-1, 1]^n,
        u ~ U[-1, 1]^m, LS, and :data:`~qsid_core.quantization.quantize.LETTER_QUANTIZER`
        (subtractive dither, per-channel range from the data's min/max, **no**
        guard band). It differs from ``SweepConfig()`` only in ``guard=False``.
        ``overrides`` replace any field (e.g. ``bits``, ``mpc``).
        """
        base = cls(
            system=system,
            bits=tuple(range(1, 17)),
            realizations=50,
            trajectories=200,
            steps=1000,
            quantizer=LETTER_QUANTIZER,
            estimator="ls",
            input_amplitude=1.0,
        )
        return replace(base, **overrides) if overrides else base

    def __post_init__(self) -> None:
        object.__setattr__(self, "bits", parse_bits(self.bits))
        check_int("realizations", self.realizations, 1, 10000)
        check_int("trajectories", self.trajectories, 1, 100_000)
        check_int("steps", self.steps, 1, 1_000_000)
        check_int("data seed", self.data_seed, 0)
        check_int("dither seed", self.dither_seed, 0)
        check_choice("estimator", self.estimator, ESTIMATORS)
        object.__setattr__(
            self, "input_amplitude", check_float("input amplitude", self.input_amplitude, 0.0, 1e12, lo_open=True)
        )
        object.__setattr__(
            self, "state_amplitude", check_float("state amplitude", self.state_amplitude, 0.0, 1e12, lo_open=True)
        )
        check_float("theta", self.theta, 0.0, 1.0, lo_open=True, hi_open=True)
        if self.rho is not None:
            check_float("rho", self.rho, 0.0, lo_open=True)
        if not isinstance(self.quantizer, QuantizerSpec):
            raise ConfigError("quantizer must be a QuantizerSpec")
        object.__setattr__(self, "input_bits", parse_input_bits(self.input_bits))
        object.__setattr__(self, "noise", parse_noise(self.noise))
        object.__setattr__(self, "state_bits", parse_state_bits(self.state_bits))
        object.__setattr__(self, "noise_known", check_bool("noise_known", self.noise_known))
        check_sweep_parts(self.system, self.mpc, self.rho)
