"""The values a front end holds -> the engine's configuration, for either kind of plant (pure functions).

:func:`study_config` is the one entry: a linear plant's :class:`~qsid_core.studies.experiment.SweepConfig` (with
its :class:`~qsid_core.control.mpc.MPCConfig` and :class:`~qsid_core.QuantizerSpec`) or a nonlinear plant's
:class:`~qsid_core.studies.KoopmanConfig`, chosen by the plant the values name, and the estimators shown. Bad input
is one line in plain words (:class:`~app.settings.check.InputError`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from app.settings.check import InputError, check_setting
from app.settings.schema import SETTINGS, engine_field, plain
from qsid_core import LTISystem, MPCConfig, QsidError, QuantizerSpec, SweepConfig
from qsid_core.plant import get_nonlinear
from qsid_core.studies import KoopmanConfig

from .typed import fixed_range, parse_vector, state_box, weights_from_log
from .values import ALL_BITS, IDENT_CHOICES, Values, is_nonlinear, resolve_system, stand_in

__all__ = [
    "StudyConfig",
    "study_config",
    "quantizer_spec",
    "mpc_config",
    "sweep_config",
    "koopman_config",
    "estimators",
]


@dataclass(frozen=True)
class StudyConfig:
    """What the engine's study of a front end's values takes: the configuration (linear or nonlinear, by the
    plant), the estimators shown, and for a linear plant the system resolved and what the panel says about it."""

    config: SweepConfig | KoopmanConfig
    estimators: tuple[str, ...]
    system: LTISystem | None = None
    notes: tuple[str, ...] = ()


def study_config(v: Values) -> StudyConfig:
    """The engine configuration of ``v``: :func:`koopman_config` for a nonlinear plant, :func:`sweep_config` for a
    linear one (InputError in plain words for values the engine refuses)."""
    if is_nonlinear(v.system):  # (a plant file is read anew each time: it may have been edited)
        cfg, ests = koopman_config(v)
        return StudyConfig(cfg, tuple(ests))
    return _linear_study(v)


@lru_cache(maxsize=128)
def _linear_study(v: Values) -> StudyConfig:
    """:func:`study_config` of a linear plant, made once per values (a tab's change asks for it several times, and
    every tab of a class on the same settings; the result is immutable)."""
    choice = resolve_system(v)
    return StudyConfig(sweep_config(v, choice.system), tuple(estimators(v.identification)), choice.system, choice.notes)


def quantizer_spec(v: Values, n: int, m: int) -> QuantizerSpec:
    """The quantizer of the panel (dither, range mode, guard band, fixed range)."""
    fixed = fixed_range(v.fixed_range, n, m) if v.range_mode == "fixed" else None
    try:
        return QuantizerSpec(dither=v.dither, range_mode=v.range_mode, guard=bool(v.guard), fixed_range=fixed)
    except QsidError as exc:
        raise InputError(str(exc)) from None


def estimators(choice: str) -> tuple:
    """Panel choice ("LS", "BCLS", "LS + BCLS") -> engine estimators."""
    if choice not in IDENT_CHOICES:
        raise InputError(f"identification must be one of {', '.join(IDENT_CHOICES)}; got {choice!r}")
    return IDENT_CHOICES[choice]


def mpc_config(v: Values, system: LTISystem) -> MPCConfig:
    """The MPC of the panel; log sliders are turned into weights, empty x0 = the system's."""
    n, m = system.n, system.m
    Q = weights_from_log(v.log_q) if len(v.log_q) == n else None
    R = weights_from_log(v.log_r) if len(v.log_r) == m else None
    names = ", ".join(system.state_names)
    x0 = parse_vector(v.x0, "x0", n, f" (one per state: {names})")
    x_ref = parse_vector(v.x_ref, "x_ref", n, f" (one per state: {names})")
    x_max = state_box(v.x_max, n, names)
    xf_max = state_box(v.terminal_box, n, names, "terminal box")
    qf_text = (v.qf or "").strip()
    if qf_text.lower() in ("", "dare"):
        Qf = None
    elif qf_text == "Q":
        assert system.Q is not None  # LTISystem fills Q in __post_init__
        Qf = Q if Q is not None else tuple(float(x) for x in np.diag(system.Q))
    else:
        k = len(qf_text.replace(",", " ").replace(";", " ").split())
        Qf = parse_vector(qf_text, "Qf", 1 if k == 1 else n, f" ('dare', 'Q', one number or one per state: {names})")
    reference = (v.reference or "").strip() or None
    try:
        if reference is not None:
            from qsid_core.control import parse_reference

            parse_reference(reference, system.state_names)
        return MPCConfig(
            **_plain_args(v, "mpc"),  # horizon, closed-loop steps, verdict steps, loop noise and seed
            u_max=float(v.u_max),
            Q=Q,
            R=R,
            x0=x0,
            x_ref=x_ref,
            reference=reference,
            tracking=v.tracking,
            x_max=x_max,
            xf_max=xf_max,
            Qf=Qf,
            disturbance=float(v.disturbance),
            disturbance_kind=v.disturbance_kind,
            feedback_bits=int(v.feedback_bits) or None,
        )
    except QsidError as exc:
        raise InputError(str(exc)) from None


def _what_ifs(v: Values, system: LTISystem) -> tuple:
    """The panel's input word length and sensor noise as engine values (InputError in plain words)."""
    from qsid_core.quantization import channel_bits
    from qsid_core.studies import parse_input_bits, parse_noise, parse_state_bits

    try:
        ib, sb = parse_input_bits(v.input_bits), parse_state_bits(v.state_bits)
        channel_bits(ALL_BITS[0], system.n, system.m, ib, sb)
        noise = parse_noise(v.noise) if (v.noise or "").strip() else (0.0,)
    except QsidError as exc:
        raise InputError(str(exc)) from None
    if len(noise) not in (1, system.n):
        raise InputError(
            f"sensor noise: give one σ for every state or one per state "
            f"({', '.join(system.state_names)}); got {len(noise)}"
        )
    return ib, sb, noise


def _plain_args(v: Values, config: str) -> dict[str, Any]:
    """The engine arguments of the settings that go to ``config`` ("sweep" or "mpc") as they are, each checked
    by the table's rules first (:func:`app.settings.schema.plain`)."""
    return {engine_field(s): check_setting(s, getattr(v, s.name), slider=False) for s in plain(config)}


def sweep_config(v: Values, system: LTISystem) -> SweepConfig:
    """The whole engine configuration for ``v`` (all word lengths :data:`ALL_BITS`; b is the one drawn in 3-D)."""
    if not ALL_BITS[0] <= int(v.bits) <= ALL_BITS[-1]:
        raise InputError(f"word length b must be between {ALL_BITS[0]} and {ALL_BITS[-1]}; got {v.bits}")
    if not v.rho_auto and not (np.isfinite(v.rho) and v.rho > 0):
        raise InputError(f"rho must be a positive number (or tick 'rho auto'); got {v.rho}")
    if not (np.isfinite(v.target) and 0 < v.target <= 1):
        raise InputError(f"target share of stabilized loops must be in (0, 1]; got {v.target}")
    if not (np.isfinite(v.cost_gap) and v.cost_gap >= 0):
        raise InputError(f"cost gap must be >= 0 (relative: 0.01 = 1 %); got {v.cost_gap}")
    input_bits, state_bits, noise = _what_ifs(v, system)
    try:
        return SweepConfig(
            system=system,
            bits=ALL_BITS,
            **_plain_args(v, "sweep"),  # realizations, data size, seeds, amplitudes, theta
            quantizer=quantizer_spec(v, system.n, system.m),
            estimator=estimators(v.identification)[0],
            mpc=mpc_config(v, system),
            rho=None if v.rho_auto else float(v.rho),
            input_bits=input_bits,
            state_bits=state_bits,
            noise=noise,
            noise_known=bool(v.noise_known),
        )
    except InputError:
        raise
    except QsidError as exc:
        raise InputError(str(exc)) from None


def _mpc(v: Values, system: LTISystem) -> MPCConfig:
    """The Koopman MPC of the panel: horizon, loop length, input bound, weights, x0, Qf; the linear loops' own
    settings (references, boxes, disturbances) are not used (their panel values are reset, not read)."""
    defaults = Values()
    unused = {
        s.name: getattr(defaults, s.name)
        for s in SETTINGS
        if s.values and s.engine is not None and s.engine.startswith("mpc.") and s.nonlinear is None
    }
    m = mpc_config(v.replace(**unused), system)
    return MPCConfig(horizon=m.horizon, steps=m.steps, u_max=m.u_max, Q=m.Q, R=m.R, x0=m.x0, Qf=m.Qf, verify_steps=None)


#: (panel setting, KoopmanConfig field) of every setting a nonlinear run takes as it is, from the settings table:
#: the system, the word lengths, the dictionary and the estimator, and the quantizer's and the MPC's (nested) are
#: built by hand.
_PLAIN = tuple(
    (s.name, s.nonlinear)
    for s in SETTINGS
    if s.values
    and s.nonlinear is not None
    and "." not in s.nonlinear
    and s.nonlinear not in ("system", "bits", "lifting", "estimator")
)


def koopman_config(v: Values) -> tuple[KoopmanConfig, tuple[str, ...]]:
    """The nonlinear sweep of the panel (every word length of the panel's slider) and the estimators shown.

    Raises
    ------
    InputError
        A value the engine refuses (a bad dictionary, an x0 of the wrong length, ...), in one line.
    """
    if not is_nonlinear(v.system):
        raise InputError(f"{v.system!r} is not a nonlinear plant")
    if not ALL_BITS[0] <= int(v.bits) <= ALL_BITS[-1]:
        raise InputError(f"word length b must be between {ALL_BITS[0]} and {ALL_BITS[-1]}; got {v.bits}")
    try:
        plant = get_nonlinear(v.system)
        system = stand_in(plant)
        cfg = KoopmanConfig(
            system=v.system,
            lifting=str(v.lifting).strip(),
            bits=ALL_BITS,
            quantizer=quantizer_spec(v, plant.n, plant.m),
            mpc=_mpc(v, system),
            **{path: getattr(v, name) for name, path in _PLAIN},
        )
        cfg.dictionary()  # a bad dictionary: one line now
    except QsidError as exc:
        raise InputError(str(exc)) from None
    return cfg, estimators(v.identification)
