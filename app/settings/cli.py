"""``qsid`` options generated from the settings table (:data:`~app.settings.schema.SETTINGS`).

Every row with a ``flag`` becomes one argparse option in its ``cli_group``: its type checks the value as
the panel does (an integer option takes an integer, a number a finite one inside the setting's range),
its default is the engine's (or the config ``base`` given, e.g. the letter's), its help ends with that
default. A study's command takes the settings with a path in its config (``study="datalength"``: the
``datalength`` column), with that config's defaults. ``--seed`` (one seed for the data and the dither) is
declared and resolved here, once (:func:`add_seed_option`, :func:`given_seeds`). Options whose value is not
one setting's (``--bits``, ``--limits``, ``--disturbance``, ...) are written by hand in :mod:`app.cli.parser`.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import Any

from .schema import BY_NAME, SETTINGS, Setting, cli_default, hint_text, nonlinear_default, path_value, resolve

__all__ = [
    "add_setting_options",
    "add_option",
    "add_seed_option",
    "given_seeds",
    "study_values",
    "SEEDED",
    "int_type",
    "float_type",
    "shown",
]

#: The settings ``--seed`` sets where they are not typed themselves.
SEEDED = ("data_seed", "dither_seed")


def int_type(name: str, lo: int | None) -> Callable[[str], int]:
    """An argparse type: an integer (a float or a word is refused), at least ``lo``."""

    def conv(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer; got {text!r}") from None
        if lo is not None and v < lo:
            kind = "positive" if lo == 1 else f">= {lo}"
            raise argparse.ArgumentTypeError(f"must be {kind}; got {v}")
        return v

    conv.__name__ = name
    return conv


def float_type(lo: float | None = None, hi: float | None = None) -> Callable[[str], float]:
    """An argparse type: a finite number, at least ``lo`` and at most ``hi``."""

    def conv(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a number; got {text!r}") from None
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"must be finite; got {text!r}")
        if lo is not None and v < lo:
            raise argparse.ArgumentTypeError(f"must be >= {lo:g}; got {text!r}")
        if hi is not None and v > hi:
            raise argparse.ArgumentTypeError(f"must be at most {hi:g}; got {text!r}")
        return v

    conv.__name__ = "number"
    return conv


def shown(value: Any) -> str:
    """A default as the help shows it (on/off, numbers in short form)."""
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, float):
        return format(value, "g")
    return str(value)


def _nonlinear_note(s: Setting, default: Any) -> str:
    """``"; nonlinear plants: X"`` where a setting of both plant kinds has another default for a nonlinear one."""
    if s.nonlinear is None or s.engine is None:
        return ""
    nd = nonlinear_default(s)
    if nd is None or nd == default:
        return ""
    return f"; nonlinear plants: {shown(nd)}"


def _kwargs(
    s: Setting, base: Any, help_text: str | None = None, default: Any = ..., plants: bool = True
) -> dict[str, Any]:
    """argparse's keywords of ``s``'s flag; ``plants``: the help names a nonlinear plant's other default."""
    default = cli_default(s, base) if default is ... else default
    shown_default = resolve(s.default) if default is None else default
    help_text = hint_text(s, help_text or s.cli_help) or s.label
    if "default:" not in help_text:
        note = _nonlinear_note(s, shown_default) if plants else ""
        help_text += f" (default: {shown(shown_default) or 'none'}{note})"
    kw: dict[str, Any] = {"dest": s.dest, "default": default, "help": help_text}
    if s.type is bool:
        # on by the engine's default: --flag / --no-flag (a base like the letter's may turn it off); else a switch
        kw["action"] = argparse.BooleanOptionalAction if resolve(s.default) else "store_true"
        return kw
    if s.metavar:
        kw["metavar"] = s.metavar
    if s.type is int:
        kw["type"] = int_type(s.name, None if s.min is None else int(s.min))
    elif s.type is float:
        kw["type"] = float_type(s.min)
    choices = resolve(s.choices)
    if choices:
        kw["choices"] = choices
    return kw


def add_setting_options(
    group: argparse._ActionsContainer,
    cli_group: str,
    base: Any = None,
    helps: dict[str, str] | None = None,
    study: str | None = None,
) -> None:
    """Add the option of every setting of ``cli_group`` to ``group``.

    ``base``: a SweepConfig (or QuantizerSpec) whose values are the defaults where it holds them, e.g.
    ``SweepConfig.letter()``; ``helps``: a command's own help text of a setting, by name. ``study``
    (``"datalength"``): only the settings with a path in that study's config ``base``, whose values there are
    the defaults (a "not given" default, None, stays None).
    """
    for s in SETTINGS:
        if s.flag is None or s.cli_group != cli_group:
            continue
        help_text = (helps or {}).get(s.name)
        if study is None:
            group.add_argument(s.flag, **_kwargs(s, base, help_text))
        elif (path := getattr(s, study)) is not None:
            default = s.cli_default if s.cli_default is not ... else path_value(base, path)
            group.add_argument(s.flag, **_kwargs(s, None, help_text, default, plants=False))


def study_values(args: argparse.Namespace, study: str) -> dict[str, Any]:
    """The parsed values of the generated options of ``study``'s settings (``"datalength"``) by their top-level
    field in its config (the quantizer's are read apart); options not given (None) are left out."""
    out = {}
    for s in SETTINGS:
        path = getattr(s, study)
        if s.flag is not None and path is not None and "." not in path and getattr(args, s.dest, None) is not None:
            out[path] = getattr(args, s.dest)
    return out


def add_seed_option(group: argparse._ActionsContainer) -> None:
    """``--seed N``: both seeds of :data:`SEEDED` where they are not typed (:func:`given_seeds`)."""
    group.add_argument(
        "--seed",
        type=int_type("non-negative integer", 0),
        default=None,
        metavar="N",
        help="seed of both the data and the dither streams (sets --data-seed and --dither-seed)",
    )


def given_seeds(args: argparse.Namespace) -> dict[str, int]:
    """The seeds the command line gives: each one typed (``--data-seed``), else ``--seed``'s; a seed neither
    gives is left out (the config's default)."""
    seed = getattr(args, "seed", None)
    out = {}
    for name in SEEDED:
        value = getattr(args, name, None)
        if value is None:
            value = seed
        if value is not None:
            out[name] = value
    return out


def add_option(group: argparse._ActionsContainer, name: str, default: Any = ..., help_text: str | None = None) -> None:
    """Add the option of the one setting ``name`` to ``group`` (a command's own ``default`` and ``help_text``
    where it differs from the table's; a command's own default is its only one)."""
    s = BY_NAME[name]
    assert s.flag is not None, f"setting {name!r} has no generated flag"
    group.add_argument(s.flag, **_kwargs(s, None, help_text, default, plants=default is ...))
