"""``qsid-dashboard``'s command line: the parser, the checks of its values, and the settings a new tab starts
from (``--settings FILE``, ``--system FILE``). Nothing here starts a thread or a server: a bad option is one
line and exit status 2 before anything runs. The port is checked first (:func:`check_options`).
"""

from __future__ import annotations

import argparse
import os
import sys

from qsid_core import ConfigError, QsidError, __version__

from .cache import DEFAULT_MB
from .koopman_settings import is_nonlinear, nonlinear_values
from .lessons import get_lesson, lesson_names
from .netcheck import NEXT_FREE_TRIES, OneLineParser, check_address, port_number
from .pool import DEFAULT_TIMEOUT
from .settings import INTERACTIVE, PAPER_SCALE, SYSTEM_CHOICES, Values
from .share import load_settings_file, values_for_plant_file
from .start import START, opens_on_start

__all__ = ["STARTING_SYSTEMS", "check_lesson", "check_options", "parser", "read_options"]

#: Systems a tab can start with (the panel's presets; 'custom' is typed in the panel).
STARTING_SYSTEMS = tuple(x for x in SYSTEM_CHOICES if x != "custom")


def check_lesson(name: str) -> str:
    """``name`` if it is a lesson; QsidError (one line, listing the lessons) otherwise."""
    try:
        get_lesson(name)
    except KeyError as exc:
        raise QsidError(exc.args[0]) from None
    return name


#: The help of ``--port`` and ``--next-free-port``.
PORT_HELP = (
    "port 0-65535 (default 8080; 0: any free port); one that cannot be bound (in use, below 1024 without the "
    "right) is one line and exit status 2"
)
NEXT_FREE_HELP = (
    f"if --port is in use, take the next free one (up to {NEXT_FREE_TRIES} further; the URL printed says so)"
)


def parser() -> argparse.ArgumentParser:
    """The parser of ``qsid-dashboard`` (its errors are one line; see :class:`.netcheck.OneLineParser`)."""
    p = OneLineParser(
        prog="qsid-dashboard",
        description="Live dashboard: quantized data -> identification -> MPC. Open the printed URL in a browser.",
    )
    p.add_argument("--version", action="version", version=f"qsid-dashboard {__version__}")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument(
        "--port",
        type=port_number,
        default=8080,
        help=PORT_HELP,
    )
    p.add_argument("--next-free-port", action="store_true", help=NEXT_FREE_HELP)
    p.add_argument(
        "--system",
        default="dc-motor",
        metavar="NAME|FILE",
        help=f"initial system of new tabs: a preset ({', '.join(STARTING_SYSTEMS)}) or a .toml/.json plant file "
        "as qsid --system reads it (opened as the panel's custom system)",
    )
    p.add_argument(
        "--scale",
        default="interactive",
        choices=("interactive", "paper"),
        help=f"initial data size: interactive ({INTERACTIVE['trajectories']} x {INTERACTIVE['steps']}, "
        f"{INTERACTIVE['realizations']} realizations) or paper ({PAPER_SCALE['trajectories']} x "
        f"{PAPER_SCALE['steps']}, {PAPER_SCALE['realizations']})",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=2,
        help="processes for the quantization and closed-loop work, shared by all tabs (0 = in-process; default 2)",
    )
    p.add_argument(
        "--task-timeout",
        type=float,
        default=DEFAULT_TIMEOUT,
        metavar="SECONDS",
        help=f"a pool task running longer counts as hung: its worker is replaced (default {DEFAULT_TIMEOUT:g})",
    )
    p.add_argument(
        "--max-tabs",
        type=int,
        default=None,
        metavar="N",
        help="serve at most N tabs at once; further tabs get a page saying the dashboard is full (default: no limit)",
    )
    p.add_argument(
        "--cache-mb",
        type=int,
        default=DEFAULT_MB,
        metavar="MB",
        help=f"memory budget of the results cache shared by all tabs (default {DEFAULT_MB})",
    )
    p.add_argument(
        "--settings",
        metavar="FILE",
        default=None,
        help="start every new tab from a settings file (saved with the panel's 'Download settings')",
    )
    p.add_argument(
        "--presenter",
        action="store_true",
        help="open new tabs in presenter mode: plot text 18 px, panel text 16 px, thick lines, a wide 3-D scene",
    )
    p.add_argument(
        "--lesson",
        default=None,
        metavar="NAME",
        help=f"open new tabs on a lesson: {', '.join(lesson_names()[1:])} (default: {START} for the default "
        "system without --settings, else none)",
    )
    return p


def _check_ranges(args: argparse.Namespace) -> None:
    """The numeric options within their ranges (ConfigError naming the option otherwise)."""
    cpus = os.cpu_count() or 1
    if args.workers < 0 or args.workers > 4 * cpus:
        raise ConfigError(
            f"--workers must be between 0 and {4 * cpus} (this machine has {os.cpu_count()} CPUs); got {args.workers}"
        )
    if not 16 <= args.cache_mb <= 65536:
        raise ConfigError(f"--cache-mb must be between 16 and 65536; got {args.cache_mb}")
    if not (args.task_timeout > 0 and args.task_timeout < 1e6):
        raise ConfigError(f"--task-timeout must be a positive number of seconds; got {args.task_timeout}")
    if args.max_tabs is not None and not 1 <= args.max_tabs <= 10000:
        raise ConfigError(f"--max-tabs must be between 1 and 10000; got {args.max_tabs}")


def _starting_settings(args: argparse.Namespace) -> Values | None:
    """What every new tab starts from: ``--settings FILE``, a plant file given as ``--system`` opened as the
    panel's custom system (what the panel changes in it is printed as notes), or None (the preset's defaults).
    A plant file sets ``args.system`` to a preset the settings then override."""
    settings = None if args.settings is None else load_settings_file(args.settings)
    if args.system not in STARTING_SYSTEMS:
        size = PAPER_SCALE if args.scale == "paper" else INTERACTIVE
        settings, notes = values_for_plant_file(args.system, settings or Values().replace(**size))
        for msg in notes:
            print(f"qsid-dashboard: note: {msg}", file=sys.stderr, flush=True)
        args.system = STARTING_SYSTEMS[0]  # unused: the settings say which system
    elif settings is None and is_nonlinear(args.system):  # a nonlinear preset: its own data size and MPC
        settings = nonlinear_values(args.system, Values(), paper=args.scale == "paper")
    return settings


def check_options(args: argparse.Namespace) -> tuple[Values | None, str | None]:
    """The parsed options checked, the port first (bound on ``--host`` before anything else is read).

    Sets ``args.asked_port`` to the port asked for and ``args.port`` to the one to listen on (another one only
    with ``--next-free-port``). Returns the settings every new tab starts from (None: the preset's defaults at
    ``--scale``) and a warning line if ``--host`` reaches beyond this machine.

    Raises
    ------
    QsidError
        The port cannot be bound, ``--host`` is not an address of this machine, an option is out of range, the
        lesson is unknown, or the settings or plant file is bad (one line, naming the option or file).
    """
    args.asked_port = args.port
    args.port, warning = check_address(args.host, args.port, args.next_free_port)
    _check_ranges(args)
    if args.lesson is not None:
        check_lesson(args.lesson)
    settings = _starting_settings(args)
    if opens_on_start(args.lesson, settings, args.system):
        args.lesson = START
    return settings, warning


def read_options(argv: list[str] | None) -> tuple[argparse.Namespace, Values | None, str | None]:
    """``argv`` parsed and checked before anything starts (:func:`check_options`).

    Returns
    -------
    args : argparse.Namespace
        The options (``args.system`` a preset; ``args.port`` the port to listen on).
    settings : Values or None
        What every new tab starts from (None: the preset's defaults at ``--scale``).
    warning : str or None
        ``--host`` reaches beyond this machine: the line to print.

    Raises
    ------
    QsidError
        As :func:`check_options`.
    SystemExit
        ``--help``, ``--version``, or an option argparse refuses (exit status 2, one line).
    """
    args = parser().parse_args(argv)
    settings, warning = check_options(args)
    return args, settings, warning
