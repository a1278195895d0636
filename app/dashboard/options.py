"""``qsid-dashboard``'s command line: the parser, the checks of its values, and the settings a new tab starts
from (``--settings FILE``, ``--system FILE``). Nothing here starts a thread or a server: a bad option is one
line and exit status 2 before anything runs.

The port is checked first (:func:`check_options`, :func:`check_address`): the port asked for is bound here, on
every address of ``--host``, before anything else runs: a port without the right to bind it (below 1024 for a
user), a port in use or an address that is not this machine's is one line and exit status 2. The server never
moves to another port unless asked (``--port 0``, ``--next-free-port``).
"""

from __future__ import annotations

import argparse
import errno
import ipaddress
import os
import socket
import sys

from app.frames.cache import DEFAULT_MB
from app.lessons.start import START, opens_on_start
from app.lessons.table import get_lesson, lesson_names
from app.settings.files import load_settings_file, values_for_plant_file
from app.settings.values import INTERACTIVE, PAPER_SCALE, SYSTEM_CHOICES, Values, is_nonlinear, nonlinear_values
from qsid_core import ConfigError, QsidError, __version__

from .pool import DEFAULT_TIMEOUT

__all__ = ["STARTING_SYSTEMS", "check_lesson", "check_options", "parser", "read_options"]
__all__ += ["NEXT_FREE_TRIES", "OneLineParser", "check_address", "port_number", "who_can_connect"]


# ----- the address: --host and --port checked before anything starts -----------------------------------------
class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (and exit status 2), not the usage block."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def port_number(text: str) -> int:
    """argparse type of ``--port``: 0 (any free port) .. 65535."""
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number; got {text!r}") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"must be between 0 and 65535 (0: any free port); got {port}")
    return port


#: Ports ``--next-free-port`` tries after the one asked for (then it gives up with one line).
NEXT_FREE_TRIES = 100


def _addresses(host: str) -> list[tuple[int, str]]:
    """(family, address) of every address ``host`` resolves to (what the server will listen on).

    Raises
    ------
    ConfigError
        ``host`` cannot be resolved.
    """
    try:
        infos = socket.getaddrinfo(host, None, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError, OSError) as exc:
        raise ConfigError(f"--host {host!r} cannot be resolved ({exc})") from None
    return sorted({(int(i[0]), str(i[4][0])) for i in infos})


def _bind_error(family: int, addr: str, port: int) -> OSError | None:
    """Why a listening socket cannot be bound to ``addr``:``port`` now (None: it can), with the options the server's
    own socket will have (``SO_REUSEADDR`` as asyncio sets it; IPv6 only on an IPv6 address)."""
    try:
        with socket.socket(family, socket.SOCK_STREAM) as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            if family == socket.AF_INET6:
                s.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_V6ONLY, 1)
            s.bind((addr, port))
            s.listen(1)
    except OSError as exc:
        return exc
    return None


def _port_refused(host: str, addr: str, port: int, exc: OSError) -> str:
    """The one line saying why ``port`` cannot be used on ``host`` (``addr``: the address that refused it)."""
    where = f"--port {port} on {host}" + (f" ({addr})" if addr != host else "")
    if exc.errno in (errno.EACCES, errno.EPERM):
        low = " (ports below 1024 need root or the CAP_NET_BIND_SERVICE capability)" if 0 < port < 1024 else ""
        return (
            f"{where}: permission denied{low}; use a port from 1024 up, e.g. --port 8080, or --port 0 for any free port"
        )
    if exc.errno == errno.EADDRINUSE:
        return (
            f"{where} is in use by another program; stop it, choose another --port, add --next-free-port to take "
            "the next free one, or use --port 0 for any free port"
        )
    return f"{where} cannot be used ({exc.strerror or exc})"


def check_address(host: str, port: int, next_free: bool = False) -> tuple[int, str | None]:
    """Resolve ``host`` and bind ``port`` on every address it names, before anything else starts.

    Returns the port to listen on (``port``; with ``next_free``, the first free one after a taken ``port``) and a
    warning if ``host`` reaches beyond this machine.

    Raises
    ------
    ConfigError
        ``host`` cannot be resolved or is not an address of this machine, or ``port`` cannot be bound (no
        permission, in use, ...): one line naming the option and what to do.
    """
    addrs = _addresses(host)
    for family, addr in addrs:  # is the address ours? (any free port: the port is checked below)
        exc = _bind_error(family, addr, 0)
        if exc is not None:
            raise ConfigError(
                f"--host {host!r} ({addr}) is not an address of this machine ({exc.strerror or exc})"
            ) from None
    tries = NEXT_FREE_TRIES + 1 if next_free and port != 0 else 1
    candidates = range(port, min(65536, port + tries))
    for candidate in candidates:
        refused = next(((a, e) for f, a in addrs if (e := _bind_error(f, a, candidate)) is not None), None)
        if refused is None:
            break
        if refused[1].errno != errno.EADDRINUSE or len(candidates) == 1:  # another port would not help
            raise ConfigError(_port_refused(host, refused[0], candidate, refused[1]))
    else:
        raise ConfigError(
            f"--port {port} and the {len(candidates) - 1} ports after it on {host} are in use (--next-free-port); "
            "choose another --port, or use --port 0 for any free port"
        )
    ips = [ipaddress.ip_address(a.split("%")[0]) for _, a in addrs]
    if all(ip.is_loopback for ip in ips):
        return candidate, None
    return candidate, (
        f"warning: listening on {host} ({', '.join(a for _, a in addrs)}), not only on this machine: anyone who "
        "can reach it on the network can use the dashboard and its CPU (there is no login). Use --host "
        "127.0.0.1 to keep it private."
    )


def _own_addresses() -> list[str]:
    """This machine's non-loopback IPv4 addresses (its host name's, and the one its default route uses)."""
    found: set[str] = set()
    try:
        found |= {str(i[4][0]) for i in socket.getaddrinfo(socket.gethostname(), None, socket.AF_INET)}
    except (socket.gaierror, UnicodeError, OSError):
        pass
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.connect(("192.0.2.1", 9))  # TEST-NET-1: picks the outgoing address, sends nothing
            found.add(s.getsockname()[0])
    except OSError:
        pass
    return sorted(a for a in found if not ipaddress.ip_address(a).is_loopback)


def who_can_connect(host: str, port: int) -> str | None:
    """One note line for a server on ``host``:``port`` that others can reach (None: this machine only)."""
    try:
        addrs = sorted({str(i[4][0]) for i in socket.getaddrinfo(host, None, type=socket.SOCK_STREAM)})
    except (socket.gaierror, UnicodeError, OSError):
        return None
    ips = [ipaddress.ip_address(a.split("%")[0]) for a in addrs]
    if all(ip.is_loopback for ip in ips):
        return None
    if any(ip.is_unspecified for ip in ips):
        urls = [f"http://{a}:{port}" for a in _own_addresses()] or [f"http://<this machine's address>:{port}"]
        where = "every network of this machine"
    else:
        urls = [f"http://{host}:{port}"]
        where = f"the network of {host}"
    return (
        f"note: others connect at {', '.join(urls)} (anyone who can reach {where}; no login; "
        "--max-tabs N limits how many tabs it serves)"
    )


# ----- the options --------------------------------------------------------------------------------------------
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
    """The parser of ``qsid-dashboard`` (its errors are one line; see :class:`OneLineParser`)."""
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
