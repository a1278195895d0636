"""Sweep configuration: :class:`SweepConfig` (everything a sweep depends on) and :func:`parse_bits`.

:meth:`SweepConfig.letter` gives the letter's own settings (Section V); the plain
defaults differ from them only in the quantizer's guard band (on by default, see
:mod:`qsid_core.quantize`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .errors import ConfigError, check_choice, check_float, check_int, short_repr
from .config_checks import check_sweep_parts
from .identify import ESTIMATORS
from .mpc import MPCConfig
from .quantize import LETTER_QUANTIZER, MAX_BITS, QuantizerSpec
from .systems import LTISystem

__all__ = ["SweepConfig", "parse_bits"]


def parse_bits(spec: str | int | list | tuple | range) -> tuple[int, ...]:
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
                raise ConfigError(f"bits range {short_repr(s)} is empty (end {short_repr(hi)} < start {short_repr(lo)})")
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
    data_seed, dither_seed : int
        Seeds of the data and of the dither streams.
    quantizer : QuantizerSpec
        Dither, range mode, guard band (on by default) and fixed range.
    estimator : {"ls", "bcls"}
    mpc : MPCConfig or None
        None skips the closed loops (identification and theory only).
    theta, rho : float
        Parameters of the ultimate bound (see :func:`qsid_core.theory.ultimate_bound`);
        ``rho=None`` picks the documented default.
    """

    system: str | LTISystem = "dc-motor"
    bits: tuple = tuple(range(1, 17))
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

    @classmethod
    def letter(cls, system: str | LTISystem = "dc-motor", **overrides) -> "SweepConfig":
        """The letter's settings (Section V), which ``qsid reproduce`` uses.

        b = 1..16, 50 dither realizations, 200 runs x 1000 steps, x0 ~ U[-1, 1]^n,
        u ~ U[-1, 1]^m, LS, and :data:`~qsid_core.quantize.LETTER_QUANTIZER`
        (subtractive dither, per-channel range from the data's min/max, **no**
        guard band). It differs from ``SweepConfig()`` only in ``guard=False``.
        ``overrides`` replace any field (e.g. ``bits``, ``mpc``).
        """
        base = cls(system=system, bits=tuple(range(1, 17)), realizations=50, trajectories=200, steps=1000,
                   quantizer=LETTER_QUANTIZER, estimator="ls", input_amplitude=1.0)
        return replace(base, **overrides) if overrides else base

    def __post_init__(self) -> None:
        object.__setattr__(self, "bits", parse_bits(self.bits))
        check_int("realizations", self.realizations, 1, 10000)
        check_int("trajectories", self.trajectories, 1, 100_000)
        check_int("steps", self.steps, 1, 1_000_000)
        check_int("data seed", self.data_seed, 0)
        check_int("dither seed", self.dither_seed, 0)
        check_choice("estimator", self.estimator, ESTIMATORS)
        object.__setattr__(self, "input_amplitude",
                           check_float("input amplitude", self.input_amplitude, 0.0, 1e12, lo_open=True))
        check_float("theta", self.theta, 0.0, 1.0, lo_open=True, hi_open=True)
        if self.rho is not None:
            check_float("rho", self.rho, 0.0, lo_open=True)
        if not isinstance(self.quantizer, QuantizerSpec):
            raise ConfigError("quantizer must be a QuantizerSpec")
        if self.quantizer.dither == "tpdf" and self.quantizer.guard and min(self.bits) < 2:
            raise ConfigError("bits: tpdf dither with the guard band needs b >= 2 (its amplitude eps takes one cell "
                              "on each side of the range); start the bits at 2 or turn the guard band off")
        check_sweep_parts(self.system, self.mpc, self.rho)
