"""Settings outside a front end: as a JSON file (download / upload / ``--settings FILE``), a plant file as the
values of a panel's custom system (``--system FILE``), and the choices each setting offers a panel or a file
(pure functions, no server).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from app.lessons.table import lesson_names
from app.settings.check import InputError, check_setting
from app.settings.schema import BY_NAME, Setting, resolve
from qsid_core import QsidError, get_system
from qsid_core.plant import get_nonlinear, is_nonlinear_file

from .config import koopman_config, sweep_config
from .values import (
    IDENT_CHOICES,
    LOG_MAX,
    LOG_MIN,
    MAX_CUSTOM_STATES,
    NONLINEAR_CHOICES,
    SYSTEM_CHOICES,
    Values,
    log_from_weights,
    nonlinear_values,
    resolve_system,
)

__all__ = [
    "SETTINGS_KIND",
    "panel_choices",
    "settings_json",
    "values_from_json",
    "load_settings_file",
    "values_for_plant_file",
]

#: The "kind" tag of a settings file (and its format version).
SETTINGS_KIND, SETTINGS_VERSION = "qsid-dashboard-settings", 1
_FIELDS = {f.name: f for f in dataclasses.fields(Values)}


def panel_choices(s: Setting) -> tuple[str, ...]:
    """The choices a panel's dropdown (or a settings file) offers for setting ``s``: a front end's own (the
    lessons, the systems, the identification) or the engine's that come with the setting (() for no dropdown)."""
    own = {"lesson": lesson_names, "system": lambda: SYSTEM_CHOICES, "identification": lambda: tuple(IDENT_CHOICES)}
    if s.name in own:
        return tuple(own[s.name]())
    return tuple(resolve(s.choices))


def settings_json(v: Values) -> str:
    """The panel's settings as a small JSON document (what "Download settings" saves)."""
    return json.dumps(
        {"kind": SETTINGS_KIND, "version": SETTINGS_VERSION, "values": dataclasses.asdict(v)}, indent=2, allow_nan=False
    )


def _field_value(name: str, value: object) -> object:
    """``value`` of the settings file's field ``name``, checked by the settings table's rules (its type before
    any conversion, its range, its choices) as a panel value is; InputError in plain words if it is refused."""
    s = BY_NAME[name]
    options = (panel_choices(s) if s.control is not None else ()) or None
    try:
        return check_setting(BY_NAME[name], value, options, name=name)
    except InputError as exc:
        raise InputError(f"settings: {exc}") from None


def values_from_json(text: str | bytes) -> Values:
    """Settings saved by :func:`settings_json` back as :class:`Values` (checked: the engine accepts them).

    Missing fields keep their defaults; unknown fields, wrong types and values the engine refuses raise
    :class:`~app.settings.check.InputError` (one line).
    """
    try:
        d = json.loads(text)
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise InputError(f"settings: not a JSON file ({getattr(exc, 'msg', type(exc).__name__)})") from None
    if not isinstance(d, dict) or d.get("kind") != SETTINGS_KIND or not isinstance(d.get("values"), dict):
        raise InputError(f'settings: not a qsid settings file (needs "kind": "{SETTINGS_KIND}" and "values")')
    unknown = sorted(set(d["values"]) - set(_FIELDS))
    if unknown:
        raise InputError(f"settings: unknown field(s) {', '.join(map(str, unknown))[:200]}")
    v = Values(**{k: _field_value(k, x) for k, x in d["values"].items()})
    if v.system in NONLINEAR_CHOICES:  # a nonlinear preset: its sweep's configuration instead
        koopman_config(v)
    else:
        sweep_config(v, resolve_system(v).system)  # every value usable (InputError in plain words otherwise)
    return v


def load_settings_file(path: str | Path) -> Values:
    """``qsid-dashboard --settings FILE``: the file's settings (InputError naming the file if bad)."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"settings file {str(p)!r} " + ("is a directory" if p.is_dir() else "does not exist"))
    try:
        return values_from_json(p.read_bytes())
    except InputError as exc:
        raise InputError(f"{p.name}: {exc}") from None
    except OSError as exc:
        raise InputError(f"cannot read settings file {str(p)!r}: {exc.strerror or exc}") from None


def values_for_plant_file(path: str | Path, defaults: Values) -> tuple[Values, list[str]]:
    """``qsid-dashboard --system FILE``: the plant file the CLI reads, as the panel's custom system.

    A, B and x0 are kept exactly (their numbers written out in full); Q and R become the weight
    sliders' log10 positions, so a weight outside the sliders' range is clipped and an off-diagonal
    entry dropped: each such change is one line of the returned notes.

    Raises
    ------
    InputError
        The file cannot be read or is not a plant the engine and the panel accept (one line, naming it).
    """
    if is_nonlinear_file(path):  # a vector field: a nonlinear plant of its own in the system dropdown
        try:
            get_nonlinear(str(path))
        except QsidError as exc:
            raise InputError(f"--system {path}: {exc}") from None
        return nonlinear_values(str(path), defaults), []

    try:
        sysm = get_system(str(path))  # a preset name or a file, as qsid --system
    except QsidError as exc:
        raise InputError(f"--system {path}: {exc}") from None
    if sysm.n > MAX_CUSTOM_STATES:
        raise InputError(
            f"--system {path}: {sysm.n} states; the dashboard's panel takes at most {MAX_CUSTOM_STATES} "
            "(the CLI takes any size the engine accepts)"
        )
    rows = lambda M: "; ".join(" ".join(repr(float(x)) for x in row) for row in M)  # noqa: E731
    notes = []
    Q, R = np.asarray(sysm.Q, dtype=float), np.asarray(sysm.R, dtype=float)
    for name, W in (("Q", Q), ("R", R)):
        d = np.diag(W)
        if np.any(W != np.diag(d)):
            notes.append(f"{name} of {path} is not diagonal: the panel keeps its diagonal")
        if np.any((d > 0) & ((d < 10.0**LOG_MIN) | (d > 10.0**LOG_MAX))):
            notes.append(
                f"{name} of {path} = diag({', '.join(f'{w:g}' for w in d)}) is outside the sliders' range "
                f"1e{LOG_MIN:g}..1e{LOG_MAX:g}: clipped"
            )
    v = defaults.replace(
        system="custom",
        a_text=rows(sysm.A),
        b_text=rows(sysm.B),
        x0=", ".join(repr(float(x)) for x in np.asarray(sysm.x0, dtype=float)),
        log_q=log_from_weights(np.diag(Q)),
        log_r=log_from_weights(np.diag(R)),
    )
    resolve_system(v)  # the panel's own checks, now rather than in the first tab
    return v, notes
