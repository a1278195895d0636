"""The values a front end holds: one field per setting of the table (:class:`Values`), the choices a panel
offers, the system they name (:func:`resolve_system`), and the plant's kind, linear or nonlinear, with its own
defaults (pure functions, no server).

Everything a front end shows is computed by :mod:`qsid_core`; :mod:`app.settings.config` turns these values into
the engine's configuration (one for either kind of plant), and typed text (matrices, vectors, ranges, boxes) is
read by :mod:`app.settings.typed`, with bad input explained in plain words (:class:`InputError`). Defaults and
choices are the engine's (``SweepConfig()``, ``MPCConfig()``, ``QuantizerSpec()``, ``ESTIMATORS``); only a front
end's own choices (interactive data size, the b drawn first, both estimators side by side) are set here.

A nonlinear preset (van-der-pol, duffing, pendulum) or plant file is identified by Koopman/EDMD. Which settings
such a plant uses is the settings table's ``nonlinear`` path (:func:`app.settings.schema.nonlinear_settings`); a
panel hides the others (:data:`LINEAR_ONLY`) and shows the nonlinear plants' own (:data:`NONLINEAR_ONLY`) only for
them. A panel's linear parts (the Q and R sliders, x0, the quantizer's channels) are built from an
:class:`~qsid_core.LTISystem`; for a nonlinear plant that is :func:`stand_in`, which carries the plant's name,
sizes, state and input names, weights and start state and nothing else (no linear sweep ever runs on it).
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache, lru_cache
from typing import TYPE_CHECKING, Any, ClassVar, TypeVar, cast

import numpy as np

from app.settings.check import InputError
from app.settings.schema import BY_NAME, NONLINEAR_GROUP, SETTINGS, value_default
from qsid_core import PRESETS, LTISystem, QsidError, SweepConfig, UncontrollableWarning, get_system
from qsid_core.identification import ESTIMATORS
from qsid_core.plant import NONLINEAR_PRESETS, NonlinearSystem, get_nonlinear
from qsid_core.plant import is_nonlinear as engine_is_nonlinear
from qsid_core.studies import KOOPMAN_MPC, KoopmanConfig

from .typed import (
    LOG_MAX,
    LOG_MIN,
    format_weights,
    log_from_weights,
    matrix_text,
    panel_matrix,
    parse_vector,
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
    "MAX_CUSTOM_STATES",
    "DISPLAY_ONLY",
    "NO_LESSON",
    "InputError",
    "Values",
    "SystemChoice",
    "resolve_system",
    "stand_in",
    "matrix_text",
    "weights_from_log",
    "log_from_weights",
    "format_weights",
    "parse_vector",
    "NONLINEAR_CHOICES",
    "NONLINEAR_ONLY",
    "LINEAR_ONLY",
    "NL_INTERACTIVE",
    "NL_PAPER_SCALE",
    "is_nonlinear",
    "nonlinear_values",
    "switch_defaults",
    "scale_for",
    "scale_label",
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
#: The lesson selector's "no lesson" entry (lessons: :mod:`app.lessons`).
NO_LESSON = "(none)"
#: Largest custom system the dashboard accepts (3-D view choices grow as n^3).
MAX_CUSTOM_STATES = 12


#: Settings that only change what is drawn from results already computed for the others: a change of these
#: alone, after a complete frame, is cheap (the dashboard's fast lane, :class:`~app.dashboard.flow.FairSlots`).
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
        return _preset(v.system)
    if is_nonlinear(v.system):
        try:  # a nonlinear plant (a preset or a plant file): the panel's stand-in (its configuration: app.settings.config)
            return SystemChoice(stand_in(get_nonlinear(v.system)))
        except QsidError as exc:
            raise InputError(f"system {v.system}: {exc}") from None
    if v.system != "custom":
        raise InputError(f"unknown system {v.system!r}; choose one of {', '.join(SYSTEM_CHOICES)}")
    return _custom(v.a_text, v.b_text)


# A tab resolves its system several times per change (the panel, the study, the exports, the summary): a linear
# plant is built once per preset or pair of matrix texts (its checks took ~4 ms each time); it is immutable (its
# arrays are read-only), so every caller may hold the same one.
@cache
def _preset(name: str) -> SystemChoice:
    return SystemChoice(get_system(name))


@lru_cache(maxsize=64)
def _custom(a_text: str, b_text: str) -> SystemChoice:
    """The custom system typed as ``a_text`` and ``b_text`` (a refused pair raises, and is not kept)."""
    try:
        A = panel_matrix(a_text, "A")
        B = panel_matrix(b_text, "B")
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


#: The nonlinear presets the system dropdown offers.
NONLINEAR_CHOICES: tuple[str, ...] = tuple(NONLINEAR_PRESETS)
#: Settings only a nonlinear plant uses (the settings table's nonlinear group): hidden for a linear plant.
NONLINEAR_ONLY = tuple(s.name for s in SETTINGS if s.cli_group == NONLINEAR_GROUP and s.control is not None)
#: Panel settings a nonlinear run does not use (no ``nonlinear`` path in the table): hidden for a nonlinear plant.
#: The word length, the lesson, presenter mode and the estimator choice (the ``estimator`` setting's) stay.
LINEAR_ONLY = tuple(
    s.name
    for s in SETTINGS
    if s.control is not None and s.nonlinear is None and s.tab != "" and s.name not in ("identification",)
)
#: The interactive data size of a nonlinear plant: the current b in about a second, every b's models within a few
#: seconds, every b's Koopman MPC loops within about 15 s (see benchmarks and docs/dashboard.rst).
NL_INTERACTIVE = {"trajectories": 50, "steps": 200, "realizations": 5}
#: The nonlinear sweep's own scale (``KoopmanConfig()``: what ``qsid sweep --system van-der-pol`` runs).
NL_PAPER_SCALE = {
    "trajectories": KoopmanConfig().trajectories,
    "steps": KoopmanConfig().steps,
    "realizations": KoopmanConfig().realizations,
}
#: Settings whose default differs for a nonlinear plant: (linear panel default, nonlinear default).
_SWITCHED = ("trajectories", "steps", "realizations", "horizon", "mpc_steps", "state_amplitude")


def is_nonlinear(system: str) -> bool:
    """Whether the system dropdown's value names a nonlinear plant: a preset, or the plant file naming a
    ``vector_field`` the dashboard was started with (``qsid-dashboard --system FILE``)."""
    if system in NONLINEAR_CHOICES:
        return True
    return system not in SYSTEM_CHOICES and engine_is_nonlinear(system)


def nonlinear_values(plant: str, base: Values, paper: bool = False) -> Values:
    """``base`` for the nonlinear ``plant``, its settings still at the linear defaults moved to the nonlinear
    ones, and the data size of ``paper`` (full) or interactive scale (a new tab started on a nonlinear plant)."""
    v = base.replace(system=plant)
    return v.replace(**switch_defaults(v, plant, True)).replace(**scale_for(plant, paper))


def scale_for(system: str, paper: bool) -> dict[str, int]:
    """The data size of the panel's "Paper scale" (``paper``) or "Interactive" button for ``system``."""
    if is_nonlinear(system):
        return NL_PAPER_SCALE if paper else NL_INTERACTIVE
    return PAPER_SCALE if paper else INTERACTIVE


def scale_label(system: str, paper: bool) -> str:
    """That button's label."""
    s = scale_for(system, paper)
    kind = "Paper scale" if paper else "Interactive"
    if paper and is_nonlinear(system):
        kind = "Full scale, as qsid sweep"
    return f"{kind} ({s['trajectories']} × {s['steps']}, {s['realizations']} realizations)"


def _nonlinear_defaults(plant: NonlinearSystem) -> dict[str, Any]:
    d: dict[str, Any] = dict(NL_INTERACTIVE, horizon=KOOPMAN_MPC.horizon, mpc_steps=KOOPMAN_MPC.steps)
    d["state_amplitude"] = float(plant.amplitude)
    return d


def switch_defaults(
    values: Values, nonlinear_plant: str, to_nonlinear: bool, also: Values | None = None
) -> dict[str, Any]:
    """The panel values to change when the plant switches between linear and the nonlinear ``nonlinear_plant``:
    each setting of :data:`_SWITCHED` still at the one kind's default (or at ``also``'s: the settings of a lesson
    the person left) goes to the other kind's; a value the person chose stays."""
    lin = {k: value_default(BY_NAME[k]) for k in _SWITCHED}
    nl = _nonlinear_defaults(get_nonlinear(nonlinear_plant))
    src, dst = (lin, nl) if to_nonlinear else (nl, lin)

    def default(k: str) -> bool:
        v = getattr(values, k)
        return v == src[k] or (also is not None and v == getattr(also, k))

    return {k: dst[k] for k in _SWITCHED if default(k) and getattr(values, k) != dst[k]}
