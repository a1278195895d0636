"""Panel values -> the nonlinear sweep's configuration (pure functions, no server).

A nonlinear preset (van-der-pol, duffing, pendulum) in the system dropdown is identified by Koopman/EDMD
(:class:`~qsid_core.studies.KoopmanExperiment`). Which settings a nonlinear plant uses is the settings table's
``nonlinear`` path (:func:`app.settings.schema.nonlinear_settings`); the panel hides the others
(:data:`LINEAR_ONLY`) and shows the nonlinear plants' own (:data:`NONLINEAR_ONLY`) only for them.

The panel's linear parts (the Q and R sliders, x0, the quantizer's channels) are built from an
:class:`~qsid_core.LTISystem`; for a nonlinear plant that is :func:`stand_in`, which carries the plant's name,
sizes, state and input names, weights and start state and nothing else (no linear sweep ever runs on it).
"""

from __future__ import annotations

from typing import Any

from app.settings.schema import BY_NAME, NONLINEAR_GROUP, SETTINGS, value_default
from qsid_core import LTISystem, MPCConfig, QsidError
from qsid_core.plant import NONLINEAR_PRESETS, NonlinearSystem, get_nonlinear
from qsid_core.plant import is_nonlinear as engine_is_nonlinear
from qsid_core.studies import KOOPMAN_MPC, KoopmanConfig

from .settings import (
    ALL_BITS,
    INTERACTIVE,
    PAPER_SCALE,
    SYSTEM_CHOICES,
    InputError,
    Values,
    estimators,
    mpc_config,
    quantizer_spec,
    stand_in,
)

__all__ = [
    "NONLINEAR_CHOICES",
    "NONLINEAR_ONLY",
    "LINEAR_ONLY",
    "NL_INTERACTIVE",
    "NL_PAPER_SCALE",
    "is_nonlinear",
    "nonlinear_values",
    "stand_in",
    "koopman_config",
    "switch_defaults",
    "scale_for",
    "scale_label",
]

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


def _mpc(v: Values, system: LTISystem) -> MPCConfig:
    """The Koopman MPC of the panel: horizon, loop length, input bound, weights, x0, Qf; the linear loops' own
    settings (references, boxes, disturbances) are not used (their panel values are reset, not read)."""
    plain = Values()
    unused = {
        s.name: getattr(plain, s.name)
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
