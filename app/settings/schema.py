"""Every setting of qsid declared once: :class:`Setting` and the table :data:`SETTINGS`, read from
``settings.toml`` next to this module (one TOML table per setting, in the panel's order).

A row says what the setting is (name, type, unit, allowed range or choices, default), how the panel
shows it (label, tab, folder, kind of input, hint), its ``qsid`` flag, where it goes in the engine's
configuration (``engine``: a dotted path into :class:`~qsid_core.SweepConfig`; ``nonlinear``: one into
:class:`~qsid_core.studies.KoopmanConfig`, for a nonlinear plant; ``datalength``: one into
:class:`~qsid_core.DataLengthConfig`) and whether it changes results or only the drawing. The engine config
fields no setting sets are listed in :data:`INTERNAL`, each with its reason. From the table come the ``qsid``
options (:mod:`app.settings.cli`), the dashboard's panel (:mod:`app.dashboard.controls`) and its values
(:class:`app.settings.values.Values`), the strict type check of a panel or file value (:func:`app.settings.check.check_setting`), the
``qsid sweep`` line (:mod:`app.settings.command`) and the stages a change invalidates
(:meth:`Setting.stages`, from the engine's own :mod:`qsid_core.studies.cache_keys`).

Defaults, choices and slider ends the engine owns are written as :class:`E` references (``E("sweep.theta")``)
and read from ``SweepConfig()``, ``MPCConfig()``, ``QuantizerSpec()`` on first use: importing this module
loads no numerics (``qsid --help`` stays fast).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any

__all__ = [
    "E",
    "Setting",
    "SETTINGS",
    "BY_NAME",
    "engine",
    "resolve",
    "value_default",
    "cli_default",
    "hint_text",
    "plain",
    "engine_field",
    "nonlinear_default",
    "nonlinear_settings",
    "GROUPS",
    "DATA_GROUP",
    "WHATIF_GROUP",
    "MPC_GROUP",
    "LOOP_GROUP",
    "NONLINEAR_GROUP",
    "INTERNAL",
    "path_value",
]


@dataclass(frozen=True)
class E:
    """A value the engine owns: a dotted path into :func:`engine`'s namespace (``"mpc.horizon"``)."""

    path: str


def engine() -> SimpleNamespace:
    """The engine's defaults and choices, imported on first use (``qsid --help`` never loads numpy).

    Returns a namespace with ``sweep`` (``SweepConfig(mpc=None)``), ``mpc`` (``MPCConfig()``), ``quant``
    (``QuantizerSpec()``), ``letter`` (``SweepConfig.letter()``), ``koopman`` (``KoopmanConfig()``, the nonlinear
    sweep's), ``koopman_plant`` (its plant, for the presets' amplitude and sane box), ``systems`` (every preset:
    the linear ones, then the nonlinear ones), ``dithers``, ``range_modes``, ``estimators``, ``tracking``,
    ``u_max`` (the default bound of one input), ``bits_lo`` / ``bits_hi`` (the default sweep's ends) and
    ``datalength`` (``DataLengthConfig()``).
    """
    global _ENGINE
    if _ENGINE is None:
        from qsid_core import PRESETS, DataLengthConfig, MPCConfig, QuantizerSpec, SweepConfig
        from qsid_core.control import TRACKING
        from qsid_core.identification import ESTIMATORS
        from qsid_core.plant import NONLINEAR_PRESETS
        from qsid_core.quantization import DITHERS, RANGE_MODES
        from qsid_core.studies import KoopmanConfig

        sweep, mpc, koopman = SweepConfig(mpc=None), MPCConfig(), KoopmanConfig()
        _ENGINE = SimpleNamespace(
            sweep=sweep,
            mpc=mpc,
            quant=QuantizerSpec(),
            letter=SweepConfig.letter(mpc=None),
            koopman=koopman,
            datalength=DataLengthConfig(),
            koopman_plant=koopman.plant(),
            systems=(*PRESETS, *NONLINEAR_PRESETS),
            dithers=DITHERS,
            range_modes=RANGE_MODES,
            estimators=ESTIMATORS,
            tracking=TRACKING,
            u_max=mpc.u_max[0] if isinstance(mpc.u_max, tuple) else mpc.u_max,
            bits_lo=sweep.bits[0],
            bits_hi=sweep.bits[-1],
        )
    return _ENGINE


_ENGINE: SimpleNamespace | None = None


def resolve(value: Any) -> Any:
    """``value`` with every :class:`E` reference (also inside a tuple) replaced by the engine's value."""
    if isinstance(value, E):
        obj: Any = engine()
        for part in value.path.split("."):
            obj = getattr(obj, part)
        return obj
    if isinstance(value, tuple):
        return tuple(resolve(v) for v in value)
    return value


@dataclass(frozen=True)
class Setting:
    """One setting, declared once.

    Parameters
    ----------
    name : str
        The dashboard's :class:`~app.settings.values.Values` field and the settings file's key.
    type : type
        ``int``, ``float``, ``bool``, ``str`` or ``tuple`` (of floats): what the panel, the settings
        file and the CLI accept, checked before any conversion (an int is never a float, a bool never a number).
    default : value or E
        The default (the engine's where ``E``).
    label : str
        The panel's label (also names the setting in every message).
    control : {"slider", "number", "checkbox", "dropdown", "text"} or None
        The panel input; None: set elsewhere (the view panel, the weight sliders) or not in the panel.
    tab, folder : str
        Where in the panel ("" = above the tabs; folder: an optional folder inside the tab).
    slider : (lo, hi, step)
        A slider's range and step (values or E); a number box's step is ``step``.
    min, max : float
        Allowed range of the value everywhere (CLI, panel, file; the number box's ends).
    choices : tuple or E
        Allowed values of a dropdown or choice option (a dashboard-only list is added by the dashboard).
    unit : str
        The unit, said in help texts ("" = none).
    hint : str
        The panel's hint and, unless ``cli_help`` is given, the CLI's help; ``{engine}``, ``{panel}``,
        ``{lo}``, ``{hi}`` are filled in (:func:`hint_text`).
    flag : str or None
        The ``qsid`` flag generated from this row (None: none, or a hand-made one, ``cli_note``).
    cli_group : str
        The ``qsid`` option group of the flag.
    metavar, cli_help : str
        The flag's metavar and help text (the default is appended).
    cli_default : value
        The flag's default when it differs from ``default`` (e.g. None, ``"none"`` in the TOML file:
        "take it from --seed").
    engine : str or None
        Where the value goes in the engine: a dotted path into :class:`~qsid_core.SweepConfig`
        (``"data_seed"``, ``"quantizer.dither"``, ``"mpc.loop_seed"``); None for the front ends' own settings
        and the nonlinear plants' own.
    nonlinear : str or None
        Where the value goes for a nonlinear plant: a dotted path into :class:`~qsid_core.studies.KoopmanConfig`
        (``"lifting"``, ``"mpc.horizon"``); None: a nonlinear run cannot honour the setting (its flag is
        refused there). Its default there is ``KoopmanConfig()``'s (:func:`nonlinear_default`).
    datalength : str or None
        Where the value goes in a data-length study: a dotted path into :class:`~qsid_core.DataLengthConfig`
        (``qsid datalength`` has the flag of each such setting, its default ``DataLengthConfig()``'s).
    budget : str or None
        Where the value goes in a budget study: a dotted path into :class:`~qsid_core.studies.BudgetConfig`
        (its own fields; the study it wraps takes the sweep's or the nonlinear plant's settings).
    display : bool
        True if the setting only changes what is drawn from results already computed.
    panel_default : value or None
        The panel's default where it differs (the interactive data size).
    values : bool
        False for a CLI-only setting (no :class:`~app.settings.values.Values` field).
    cli_note : str
        How the CLI gives a setting whose flag is written by hand (its value is not the panel's).
    """

    name: str
    type: type
    default: Any
    label: str
    control: str | None = None
    tab: str = ""
    folder: str | None = None
    slider: tuple[Any, Any, Any] | None = None
    step: float | None = None
    min: float | None = None
    max: float | None = None
    choices: Any = ()
    unit: str = ""
    hint: str | None = None
    flag: str | None = None
    cli_group: str = ""
    metavar: str | None = None
    cli_help: str | None = None
    cli_default: Any = ...
    engine: str | None = None
    nonlinear: str | None = None
    datalength: str | None = None
    budget: str | None = None
    display: bool = False
    panel_default: Any = None
    values: bool = True
    cli_note: str = ""

    @property
    def dest(self) -> str:
        """The argparse destination of the flag (the setting's name)."""
        return self.name

    @property
    def flags(self) -> tuple[str, ...]:
        """The ``qsid`` flags that set this setting: the generated one (with ``--no-`` for an on/off one), or
        the hand-made one its ``cli_note`` starts with (``"--u-max X"`` -> ``--u-max``); () if none."""
        if self.flag is not None:
            return (self.flag, f"--no-{self.flag[2:]}") if self.type is bool else (self.flag,)
        word = self.cli_note.split(" ", 1)[0]
        return (word,) if word.startswith("--") else ()

    def stages(self, nonlinear: bool = False) -> tuple[str, ...]:
        """The engine's cached stages a change of this setting invalidates (none if display-only or unkeyed).

        Read from :data:`qsid_core.studies.STAGE_GROUPS` (``nonlinear``: from
        :data:`qsid_core.studies.KOOPMAN_STAGE_GROUPS`, for a nonlinear plant): a stage is invalidated if one of
        its key groups holds ``engine`` (``nonlinear``) or a field containing it.
        """
        path = self.nonlinear if nonlinear else self.engine
        if self.display or path is None:
            return ()
        from qsid_core.studies import KEY_PARTS, KOOPMAN_KEY_PARTS, KOOPMAN_STAGE_GROUPS, STAGE_GROUPS

        key_parts, stage_groups = (KOOPMAN_KEY_PARTS, KOOPMAN_STAGE_GROUPS) if nonlinear else (KEY_PARTS, STAGE_GROUPS)
        groups = {g for g, parts in key_parts.items() if any(path == p or path.startswith(p + ".") for p in parts)}
        return tuple(s for s, gs in stage_groups.items() if groups & set(gs))


def hint_text(s: Setting, text: str | None = None) -> str | None:
    """The setting's hint (or ``text``) with ``{engine}`` (the engine's default), ``{panel}`` (the panel's) and
    ``{lo}``/``{hi}`` (a slider's ends) filled in."""
    text = s.hint if text is None else text
    if text is None:
        return None
    lo, hi, _ = resolve(s.slider) if s.slider is not None else (s.min, s.max, s.step)
    return text.format(engine=resolve(s.default), panel=value_default(s), lo=lo, hi=hi)


def plain(config: str, cli: bool = False) -> tuple[Setting, ...]:
    """The numeric settings whose value goes to the engine as it is: a generated flag, an ``engine`` path in
    ``config`` (``"sweep"``: a SweepConfig field, ``"mpc"``: an MPCConfig field), type int or float. ``cli``:
    only those whose flag's value is the setting's (not None for "take it from --seed")."""
    return tuple(
        s
        for s in SETTINGS
        if s.flag is not None
        and s.engine is not None
        and s.type in (int, float)
        and (s.engine.startswith("mpc.") if config == "mpc" else "." not in s.engine)
        and not (cli and s.cli_default is None)
    )


def engine_field(s: Setting) -> str:
    """The engine config field a setting of :func:`plain` sets (``"mpc.steps"`` -> ``"steps"``)."""
    assert s.engine is not None
    return s.engine.rsplit(".", 1)[-1]


def nonlinear_default(s: Setting) -> Any:
    """The engine's default of the setting for a nonlinear plant (``KoopmanConfig()``'s; None: the plant's own,
    or a setting a nonlinear run does not use)."""
    return None if s.nonlinear is None else resolve(E("koopman." + s.nonlinear))


def nonlinear_settings() -> tuple[Setting, ...]:
    """The settings a nonlinear run honours (those with a ``nonlinear`` path)."""
    return tuple(s for s in SETTINGS if s.nonlinear is not None)


def path_value(obj: Any, path: str) -> Any:
    """The value at dotted ``path`` in ``obj`` (``"quantizer.dither"``)."""
    for part in path.split("."):
        obj = getattr(obj, part)
    return obj


def value_default(s: Setting) -> Any:
    """The setting's default in the panel and the settings file."""
    return resolve(s.panel_default if s.panel_default is not None else s.default)


def cli_default(s: Setting, base: Any = None) -> Any:
    """The flag's default; ``base`` (a SweepConfig, e.g. the letter's, or a QuantizerSpec) replaces the engine's
    where it holds it."""
    if s.cli_default is not ...:
        return s.cli_default
    if base is not None and isinstance(s.default, E) and s.default.path.startswith(("sweep.", "quant.")):
        # base: a SweepConfig, or a QuantizerSpec for the quantizer's settings alone
        obj: Any = base if s.default.path.startswith("sweep.") else getattr(base, "quantizer", base)
        return getattr(obj, s.default.path.split(".", 1)[1])
    return resolve(s.default)


_TYPES: dict[str, type] = {"int": int, "float": float, "bool": bool, "str": str, "tuple": tuple}


def _value(v: Any) -> Any:
    """A TOML value as a Setting's: ``"engine:PATH"`` -> :class:`E`, lists -> tuples."""
    if isinstance(v, str) and v.startswith("engine:"):
        return E(v.removeprefix("engine:"))
    if isinstance(v, list):
        return tuple(_value(x) for x in v)
    return v


def _load() -> tuple[dict[str, str], tuple[Setting, ...], dict[str, str]]:
    """The option groups, the settings of ``settings.toml`` (next to this module, in its order) and its
    internal fields."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover - Python 3.10
        import tomli as tomllib
    data = tomllib.loads(Path(__file__).with_name("settings.toml").read_text(encoding="utf-8"))
    groups: dict[str, str] = data["groups"]
    rows = []
    for name, row in data["settings"].items():
        kw = {k: _value(v) for k, v in row.items()}
        kw["type"] = _TYPES[row["type"]]
        if "cli_group" in kw:
            kw["cli_group"] = groups[kw["cli_group"]]
        if row.get("cli_default") == "none":
            kw["cli_default"] = None
        rows.append(Setting(name=name, **kw))
    return groups, tuple(rows), dict(data["internal"])


#: The ``qsid`` option groups by key (``cli_group`` in the table).
GROUPS: dict[str, str]
#: Every setting, in the panel's display order (tabs appear in order of first use).
SETTINGS: tuple[Setting, ...]
#: Engine config fields no setting sets, by ``"CONFIG.PATH"`` (``sweep``: SweepConfig, ``nonlinear``:
#: KoopmanConfig, ``datalength``: DataLengthConfig), each with the reason.
INTERNAL: dict[str, str]
GROUPS, SETTINGS, INTERNAL = _load()
DATA_GROUP, WHATIF_GROUP, MPC_GROUP, LOOP_GROUP, NONLINEAR_GROUP = (
    GROUPS[k] for k in ("data", "whatif", "mpc", "loop", "nonlinear")
)

#: The settings by name.
BY_NAME: dict[str, Setting] = {s.name: s for s in SETTINGS}
