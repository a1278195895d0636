"""Stop signals: SIGINT, SIGTERM and SIGHUP stop a run as Ctrl-C does, and the stop is remembered.

A library that catches ``KeyboardInterrupt`` while it works (dask's cluster while it starts) would otherwise
hide a stop; code after such a call checks :func:`check_stopped`. The program's entry point installs
:func:`stop_signal` and clears :data:`STOPPED` (``app.cli.main``).
"""

from __future__ import annotations

import threading

__all__ = ["STOPPED", "stop_signal", "check_stopped"]

#: Set by :func:`stop_signal`: a stop signal arrived (cleared by the program's entry point).
STOPPED = threading.Event()


def stop_signal(signum, frame) -> None:
    """A signal handler that stops the program as Ctrl-C does (raises KeyboardInterrupt) and remembers it."""
    STOPPED.set()
    raise KeyboardInterrupt


def check_stopped() -> None:
    """Raise KeyboardInterrupt if :func:`stop_signal` ran (after a call that may have swallowed its interrupt)."""
    if STOPPED.is_set():
        raise KeyboardInterrupt
