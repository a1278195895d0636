"""Sweep configurations of both plant kinds: :class:`SweepConfig` (everything a linear plant's sweep depends on)
and :class:`KoopmanConfig` (a nonlinear plant's: its lifting, quantized EDMD and Koopman MPC), and :func:`parse_bits`.

:meth:`SweepConfig.letter` gives the letter's own settings (Section V); the plain
defaults differ from them only in the quantizer's guard band (on by default, see
:mod:`qsid_core.quantization.quantize`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any

from ..control.koopman_mpc import CONVERGED_RADIUS
from ..control.mpc import MPCConfig
from ..errors import ConfigError, check_choice, check_float, check_int
from ..identification import Lifting, parse_lifting
from ..identification.identify import ESTIMATORS
from ..plant import NonlinearSystem, get_nonlinear
from ..plant.lti import LTISystem
from ..quantization.quantize import LETTER_QUANTIZER, MAX_BITS, QuantizerSpec
from ..validate import check_bool
from .config_checks import InputBits, check_sweep_parts, parse_bits, parse_input_bits, parse_noise, parse_state_bits

__all__ = [
    "HELD_OUT",
    "KOOPMAN_MPC",
    "KOOPMAN_MPC_UNUSED",
    "NO_CERTIFICATES",
    "InputBits",
    "KoopmanConfig",
    "SweepConfig",
    "parse_bits",
    "parse_input_bits",
    "parse_noise",
    "parse_state_bits",
]


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


#: The MPC of the nonlinear sweeps by default: 1 s horizon, 10 s of closed loop (dt = 0.05).
KOOPMAN_MPC = MPCConfig(horizon=20, steps=200, verify_steps=None)
#: What the nonlinear results say about the linear certificates.
NO_CERTIFICATES = (
    "the linear certificates (Theorem 1's error model, small gain, ultimate bound, b_letter, b_robust) "
    "assume a linear plant and do not apply to a nonlinear one: only observed outcomes are reported"
)
#: Held-out runs for the prediction error: runs, steps, and the default prediction horizon H (the error is over
#: steps 1..H).
HELD_OUT = (50, 40, 20)
#: The :class:`MPCConfig` fields the Koopman loops do not use (exact state feedback, no disturbance, regulation
#: to 0 without state constraints; the verdict is by ``radius`` and the sane box): a value other than
#: ``MPCConfig()``'s is refused, never silently ignored. ``verify_steps`` is not used either and not checked
#: (:data:`KOOPMAN_MPC` leaves it None, a linear study's MPC table may hold any value).
KOOPMAN_MPC_UNUSED = (
    "x_max",
    "xf_max",
    "x_ref",
    "disturbance",
    "disturbance_kind",
    "feedback_bits",
    "feedback_noise",
    "loop_seed",
    "reference",
    "tracking",
)


@dataclass(frozen=True)
class KoopmanConfig:
    """A word-length sweep of a nonlinear plant.

    Parameters
    ----------
    system : str or NonlinearSystem
        A nonlinear preset (``van-der-pol``, ``duffing``, ``pendulum``) or a plant.
    lifting : str
        Dictionary spec (``poly:3``, ``rbf:K``, ``identity``; see :func:`~qsid_core.identification.parse_lifting`).
    estimator : {"ls", "bcls"}
    bits : tuple of int
        Word lengths (every state and input).
    trajectories, steps : int
        Training runs and samples per run (default 2000 x 100).
    realizations : int
        Dither realizations per b.
    data_seed, dither_seed : int
        Seeds of the training data (and held-out runs, and the RBF centres) and of the dither.
    quantizer : QuantizerSpec
        Dither, range, guard band (default: subtractive, per-channel, guard band on).
    mpc : MPCConfig or None
        The Koopman MPC (default :data:`KOOPMAN_MPC`); None skips the loops. Fields the loops do not use
        (:data:`KOOPMAN_MPC_UNUSED`) must keep ``MPCConfig()``'s values.
    radius : float, > 0
        Convergence radius of the loops' verdict (2-norm of the final state).
    prediction_horizon : int, 1..40
        Steps H of the prediction error: the relative RMS over k = 1..H of the prediction of each held-out run from
        its first sample (:data:`HELD_OUT`: 50 runs of 40 samples; :func:`~qsid_core.identification.prediction_error`).
    state_amplitude : float or None, > 0
        ``a`` of the training runs' x0 ~ U[-a, a]^n (None: the plant's ``amplitude``, 2 for the presets).
    input_amplitude : float, > 0
        ``A`` of the training inputs u ~ U[-A, A]^m.
    box : float or None, > 0
        The sane box ``|x_i| <= box`` (None: the plant's, 50 for the presets): a training run beyond it is
        reported and left out; a closed loop beyond it has diverged.
    """

    system: str | NonlinearSystem = "van-der-pol"
    lifting: str = "poly:3"
    estimator: str = "ls"
    bits: tuple[int, ...] = tuple(range(2, 9))
    trajectories: int = 2000
    steps: int = 100
    realizations: int = 20
    data_seed: int = 0
    dither_seed: int = 1
    quantizer: QuantizerSpec = field(default_factory=QuantizerSpec)
    mpc: MPCConfig | None = KOOPMAN_MPC
    radius: float = CONVERGED_RADIUS
    prediction_horizon: int = HELD_OUT[2]
    state_amplitude: float | None = None
    input_amplitude: float = 1.0
    box: float | None = None

    def __post_init__(self) -> None:
        check_choice("estimator", self.estimator, ESTIMATORS)
        if not self.bits:
            raise ConfigError("bits must name at least one word length")
        object.__setattr__(self, "bits", tuple(check_int("bits", b, 1, MAX_BITS) for b in self.bits))
        check_int("trajectories", self.trajectories, 1, 100_000)
        check_int("steps", self.steps, 1, 1_000_000)
        check_int("realizations", self.realizations, 1, 10_000)
        check_int("data seed", self.data_seed, 0)
        check_int("dither seed", self.dither_seed, 0)
        if not isinstance(self.quantizer, QuantizerSpec):
            raise ConfigError("quantizer must be a QuantizerSpec")
        object.__setattr__(self, "radius", check_float("radius", self.radius, 0.0, 1e12, lo_open=True))
        check_int("prediction horizon", self.prediction_horizon, 1, HELD_OUT[1])
        amp = check_float("input amplitude", self.input_amplitude, 0.0, 1e12, lo_open=True)
        object.__setattr__(self, "input_amplitude", amp)
        for name, label in (("state_amplitude", "state amplitude"), ("box", "box")):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, check_float(label, v, 0.0, 1e12, lo_open=True))
        if self.mpc is not None:
            if not isinstance(self.mpc, MPCConfig):
                raise ConfigError("mpc must be an MPCConfig or None")
            plain = MPCConfig()
            used = [k for k in KOOPMAN_MPC_UNUSED if getattr(self.mpc, k) != getattr(plain, k)]
            if used:
                raise ConfigError(
                    f"mpc.{used[0]}: the Koopman MPC does not use it (exact state feedback, no disturbance, "
                    "regulation to 0 without state constraints); leave it at its default"
                )

    def plant(self) -> NonlinearSystem:
        """The plant (a preset by name), with this config's ``state_amplitude`` and ``box`` where set."""
        s = get_nonlinear(self.system)
        if self.state_amplitude is None and self.box is None:
            return s
        a = s.amplitude if self.state_amplitude is None else self.state_amplitude
        return replace(s, amplitude=a, box=s.box if self.box is None else self.box)

    def dictionary(self) -> Lifting:
        """The lifting for the plant's state (RBF centres over the training amplitude, seeded by ``data_seed``)."""
        s = self.plant()
        return parse_lifting(self.lifting, s.n, s.amplitude, self.data_seed)
