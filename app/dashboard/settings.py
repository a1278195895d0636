"""Panel values -> engine configuration (pure functions, no server).

Everything the dashboard shows is computed by :mod:`qsid_core`; this module only
turns what a person set in the panel (:class:`Values`, one field per setting of the
settings table :data:`app.settings.SETTINGS`) into the engine's
:class:`~qsid_core.studies.experiment.SweepConfig` / :class:`~qsid_core.control.mpc.MPCConfig`,
and explains bad input in plain words (:class:`InputError`); typed text (matrices,
vectors, ranges, boxes) is read by :mod:`app.dashboard.typed`. Defaults and choices
are the engine's (``SweepConfig()``, ``MPCConfig()``, ``QuantizerSpec()``,
``ESTIMATORS``); only the dashboard's own choices (interactive data size, the
b drawn first, both estimators side by side) are set here.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, TypeVar, cast

import numpy as np

from app.settings.check import InputError, check_setting
from app.settings.schema import BY_NAME, SETTINGS, engine_field, plain, value_default
from qsid_core import (
    PRESETS,
    LTISystem,
    MPCConfig,
    QsidError,
    QuantizerSpec,
    SweepConfig,
    UncontrollableWarning,
    get_system,
)
from qsid_core.identification import ESTIMATORS
from qsid_core.plant import NONLINEAR_PRESETS, NonlinearSystem, get_nonlinear, is_nonlinear

from .typed import (
    LOG_MAX,
    LOG_MIN,
    fixed_range,
    format_weights,
    log_from_weights,
    matrix_text,
    panel_matrix,
    parse_vector,
    state_box,
    weights_from_log,
)

__all__ = [
    "ALL_BITS",
    "INTERACTIVE",
    "PAPER_SCALE",
    "SYSTEM_CHOICES",
    "IDENT_CHOICES",
    "LABELS",
    "LOG_MIN",
    "LOG_MAX",
    "NO_LESSON",
    "InputError",
    "Values",
    "SystemChoice",
    "resolve_system",
    "stand_in",
    "matrix_text",
    "quantizer_spec",
    "mpc_config",
    "sweep_config",
    "estimators",
    "weights_from_log",
    "log_from_weights",
    "format_weights",
    "parse_vector",
]

_SWEEP = SweepConfig(mpc=None)  # the engine's defaults (no system is built: "dc-motor" stays a name)

#: Word lengths every curve is drawn over (the engine's default sweep).
ALL_BITS = _SWEEP.bits
#: The letter's data size (the engine's defaults: 200 x 1000 samples, 50 dither realizations).
PAPER_SCALE = {"trajectories": _SWEEP.trajectories, "steps": _SWEEP.steps, "realizations": _SWEEP.realizations}
#: Interactive default (the panel's defaults of the settings table): every update stays fast
#: (see benchmarks/bench_dashboard.py).
INTERACTIVE = {k: value_default(BY_NAME[k]) for k in PAPER_SCALE}
#: Systems offered in the panel (the engine's linear presets, its nonlinear ones, plus a typed linear one).
SYSTEM_CHOICES = (*PRESETS, *NONLINEAR_PRESETS, "custom")
#: Display label of each engine estimator (also the palette's colour keys).
LABELS = {e: e.upper() for e in ESTIMATORS}
#: Identification choices -> engine estimators: each estimator alone, then all side by side.
IDENT_CHOICES = {**{LABELS[e]: (e,) for e in ESTIMATORS}, " + ".join(LABELS[e] for e in ESTIMATORS): ESTIMATORS}
#: The lesson selector's "no lesson" entry (lessons: :mod:`app.dashboard.lessons`).
NO_LESSON = "(none)"
#: Largest custom system the dashboard accepts (3-D view choices grow as n^3).
MAX_CUSTOM_STATES = 12


#: Settings that only change what is drawn from results already computed for the others: a change of these
#: alone, after a complete frame, is cheap (the fast lane of :class:`~app.dashboard.flow.FairSlots`).
DISPLAY_ONLY = tuple(s.name for s in SETTINGS if s.display and s.values)


class _ValuesMethods:
    """The methods of :class:`Values` (its fields are the settings table's)."""

    def replace(self, **kw: Any) -> Values:
        return cast("Values", dataclasses.replace(self, **kw))  # type: ignore[type-var]  # a dataclass, made below

    def same_results(self, other: Values) -> bool:
        """True if ``self`` and ``other`` differ at most in :data:`DISPLAY_ONLY` settings (same results)."""
        return self.replace(**{k: getattr(other, k) for k in DISPLAY_ONLY}) == other


def _values_class() -> type:
    """:class:`Values`: a frozen dataclass with one field per setting of the table (its type and default)."""
    cls = dataclasses.make_dataclass(
        "Values",
        [(s.name, s.type, dataclasses.field(default=value_default(s))) for s in SETTINGS if s.values],
        bases=(_ValuesMethods,),
        frozen=True,
    )
    cls.__module__ = __name__
    cls.__doc__ = (
        "Everything set in one browser tab's panel: one field per setting of :data:`app.settings.SETTINGS` "
        "(defaults = the engine's, at the interactive data size). Empty ``log_q``/``log_r``/``x0`` mean "
        '"the system\'s default".'
    )
    return cls


if TYPE_CHECKING:

    class Values(_ValuesMethods):
        """Everything set in one browser tab's panel (a field per setting of the table; see ``_values_class``)."""

        __dataclass_fields__: ClassVar[dict[str, Any]]

        def __init__(self, **values: Any) -> None: ...
        def __getattr__(self, name: str) -> Any: ...

else:
    Values = _values_class()


@dataclass(frozen=True)
class SystemChoice:
    """The true system chosen in the panel and plain-words notes about it (e.g. not controllable)."""

    system: LTISystem
    notes: tuple = ()


_T = TypeVar("_T")


def _build_quietly(fn: Callable[[], _T]) -> tuple[_T, tuple[str, ...]]:
    """Call ``fn()``; return (result, notes) with an UncontrollableWarning turned into a note."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UncontrollableWarning)
        out = fn()
    notes: list[str] = []
    for w in caught:
        if issubclass(w.category, UncontrollableWarning):
            notes.append(f"{w.message}. Identification still works.")
    return out, tuple(notes)


def resolve_system(v: Values) -> SystemChoice:
    """The true system for ``v``: a preset, or A and B typed in the panel.

    Raises
    ------
    InputError
        With the offending matrix and row in plain words.
    """
    if v.system in PRESETS:
        return SystemChoice(get_system(v.system))
    if v.system in NONLINEAR_PRESETS or (v.system not in SYSTEM_CHOICES and is_nonlinear(v.system)):
        try:  # a nonlinear plant (a preset or a plant file): the panel's stand-in (its pipeline: koopman_settings.py)
            return SystemChoice(stand_in(get_nonlinear(v.system)))
        except QsidError as exc:
            raise InputError(f"system {v.system}: {exc}") from None
    if v.system != "custom":
        raise InputError(f"unknown system {v.system!r}; choose one of {', '.join(SYSTEM_CHOICES)}")
    try:
        A = panel_matrix(v.a_text, "A")
        B = panel_matrix(v.b_text, "B")
    except QsidError as exc:
        raise InputError(f"Custom system: {exc}") from None
    n = A.shape[0]
    if A.shape != (n, n):
        raise InputError(f"Custom system: A must be square (n x n); it has {A.shape[0]} rows and {A.shape[1]} columns")
    if B.shape[0] != n:
        if B.shape[1] == n and B.shape[0] != n:
            hint = " (did you type B transposed? write one row per state)"
        else:
            hint = ""
        raise InputError(f"Custom system: B must have one row per state ({n} rows, like A); it has {B.shape[0]}{hint}")
    if n > MAX_CUSTOM_STATES:
        raise InputError(f"Custom system: at most {MAX_CUSTOM_STATES} states in the dashboard; A is {n} x {n}")
    try:
        sysm, notes = _build_quietly(lambda: LTISystem("custom", A, B, description="typed in the dashboard"))
    except QsidError as exc:
        raise InputError(f"Custom system: {exc}") from None
    return SystemChoice(sysm, notes)


def stand_in(plant: NonlinearSystem) -> LTISystem:
    """The panel's linear stand-in of ``plant``: its sizes, names, weights and start state, a chain of integrators
    (never identified or controlled; it only shapes the panel's Q/R sliders, x0 and channel names)."""
    n, m, dt = plant.n, plant.m, plant.dt
    A = np.eye(n) + dt * np.eye(n, k=1)
    B = np.zeros((n, m))
    for j in range(min(n, m)):
        B[n - 1 - j, j] = dt
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (a stand-in with fewer inputs per chain may be uncontrollable: unused)
        return LTISystem(
            plant.name,
            A,
            B,
            Q=np.diag(plant.Q),
            R=np.diag(plant.R),
            x0=np.array(plant.x0),
            state_names=plant.state_names,
            input_names=plant.input_names,
            description=plant.description,
        )


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
