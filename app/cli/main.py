"""``qsid``'s entry point: parse, dispatch to a command module, turn every user error into one line.

Every user error (bad option, bad bits spec, unreadable system file, engine
``ValueError``) is one line ``qsid: error: ...`` on stderr with exit code 2, never
a traceback. Warnings (e.g. an uncontrollable custom system) are one line
``qsid: warning: ...``. Adding a command = one module (``HELP``, ``DESCRIPTION``,
``add_arguments``, ``run``) + one entry in :data:`COMMANDS`.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import warnings
from collections.abc import Callable, Sequence

from app.stop import STOPPED, stop_signal

from . import bits, budget, datalength, identify, parser, reproduce, sweep, systems
from .runner import Reporter, UsageError, one_line

__all__ = ["COMMANDS", "build_parser", "main"]

#: name -> command module, in the order ``qsid --help`` lists them.
COMMANDS = {
    "systems": systems,
    "sweep": sweep,
    "bits": bits,
    "budget": budget,
    "reproduce": reproduce,
    "datalength": datalength,
    "identify": identify,
}


def build_parser(only: str | None = "*") -> argparse.ArgumentParser:
    """The ``qsid`` argument parser (errors raise :class:`~app.cli.parser.UsageError`); ``only``: see
    :func:`app.cli.parser.build_parser`."""
    return parser.build_parser(COMMANDS, only)


def _dispatch(argv: list, rep: Reporter) -> int:
    if argv[:1] == ["--version"]:
        from qsid_core import __version__

        print(f"{parser.PROG} {__version__}")
        return 0
    name = next((a for a in argv if not a.startswith("-")), None)
    args = build_parser(name if name in COMMANDS else None).parse_args(argv)
    if args.command is None:
        raise UsageError(f"give a command: {', '.join(COMMANDS)} (see '{parser.PROG} --help')")
    rep.enabled = not getattr(args, "quiet", False)
    args.argv = tuple(argv)  # which options were typed (a nonlinear plant has defaults of its own)
    return COMMANDS[args.command].run(args, rep)


def _stop_signals_interrupt() -> dict:
    """SIGTERM (kill, a CI runner) and SIGHUP (terminal closed) stop a run as Ctrl-C does: workers stopped,
    no half-written output, exit 130; all three through :func:`app.stop.stop_signal`, which remembers the stop
    for code that checks after a library call. Returns the handlers to restore (main thread only; else none)."""
    old = {}
    STOPPED.clear()
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT):
            if (
                sig != signal.SIGINT or signal.getsignal(sig) is signal.default_int_handler
            ):  # an ignored Ctrl-C stays so
                old[sig] = signal.signal(sig, stop_signal)
    return old


def _ignore_stop_signals() -> None:
    """The stop signals this entry point took (:func:`_stop_signals_interrupt`) ignored from now on."""
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT):
            if signal.getsignal(sig) is stop_signal:
                signal.signal(sig, signal.SIG_IGN)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``qsid`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code.

    0 success, 2 bad input or engine error (one line on stderr), 1 a worker died, 130 interrupted.
    """
    rep = Reporter(True)

    def fail(message: object, code: int = 2) -> int:
        rep.line(f"error: {one_line(message)}")
        return code

    old = _stop_signals_interrupt()
    code = None
    try:
        code = _main(argv, rep, fail)
        return code
    finally:
        # The program's own run (no argv given) that was interrupted now ends: its stop signals stay ignored
        # until the process is gone. Restored, a further Ctrl-C (pressed again, or a signal arriving late)
        # would raise in the exit, or kill it by SIGINT once Python resets the handlers while it finalizes:
        # exit -2 (or a traceback) after "interrupted", not 130. A caller in the same process gets its own back.
        if not (code == 130 and argv is None):
            for sig, handler in old.items():
                signal.signal(sig, handler)


def _broken_pool() -> tuple[type[BaseException], ...]:
    """``BrokenProcessPool`` once a run has used a process pool (its module loads multiprocessing: a run without
    worker processes never imports it), else nothing to catch."""
    pool = sys.modules.get("concurrent.futures.process")
    return (pool.BrokenProcessPool,) if pool is not None else ()


def _main(argv: Sequence[str] | None, rep: Reporter, fail: Callable[..., int]) -> int:
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        warnings.showwarning = rep.warning
        try:
            code = _dispatch(list(sys.argv[1:] if argv is None else argv), rep)
            return 2 if rep.lost and code == 0 else code  # an output written elsewhere (said on stderr)
        except UsageError as exc:
            return fail(exc)
        except ValueError as exc:  # every qsid_core user error is a ValueError subclass
            return fail(exc)
        except OverflowError as exc:  # a value too large for the numerics (engines without a range check)
            return fail(f"a value is too large for the computation ({one_line(exc)}); use smaller numbers")
        except MemoryError:
            return fail("not enough memory for this run; reduce --trajectories, --steps, --realizations or --bits")
        except _broken_pool():
            return fail("a worker process died (out of memory?); try fewer --workers", 1)
        except OSError as exc:
            where = f" {exc.filename!r}" if getattr(exc, "filename", None) else ""
            return fail(f"cannot read or write{where}: {exc.strerror or exc}")
        except KeyboardInterrupt:
            _ignore_stop_signals()  # stopped and cleaned up: a further signal must not end the exit differently
            rep.line("interrupted")
            return 130
