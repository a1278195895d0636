"""The dashboard's stop: Ctrl-C, SIGTERM and SIGHUP taken on one path, and the stop bounded in time.

:func:`prepare_stop_signals` is called before any thread exists; ``main`` then starts the server in a thread
of its own, waits in :func:`wait_for_stop_signal` from the first moment of the start-up, and stops the app with
:func:`stop_app`: the pool's workers are always killed and reaped, the web server is given :data:`STOP_WAIT`
seconds. A stop during the start-up takes the same path (what exists so far is stopped).
"""

from __future__ import annotations

import signal
import threading
import time

__all__ = ["prepare_stop_signals", "wait_for_stop_signal", "stop_app", "STOP_WAIT", "RELEASE_WAIT"]

_STOP_SIGNALS = {signal.SIGINT, signal.SIGTERM, signal.SIGHUP}


def prepare_stop_signals() -> threading.Event:
    """Route Ctrl-C, SIGTERM (kill, systemd, docker stop) and SIGHUP (terminal closed) to one stop path.

    Returns the event that is set when one of them arrives. Call before any thread exists.

    The three signals are blocked in this thread, so every thread started afterwards inherits the mask
    and they stay pending until :func:`wait_for_stop_signal` takes them with ``sigtimedwait`` (a library
    that swaps the SIGINT handler from a worker thread, as OSQP does on every solve, cannot swallow them).
    Python handlers are installed as well: if a thread unblocks them again, the signal delivered there
    still only sets the event instead of killing the process by the default action.
    """
    stop = threading.Event()

    def handler(signum, frame):
        stop.set()

    for sig in _STOP_SIGNALS:
        signal.signal(sig, handler)
    signal.pthread_sigmask(signal.SIG_BLOCK, _STOP_SIGNALS)
    return stop


def wait_for_stop_signal(stop: threading.Event) -> None:
    """Block until a stop signal is pending (taken here) or ``stop`` is set (by a handler, or by a thread that
    ends the wait, such as a failed start-up); ``stop`` is set on return, so every thread can tell."""
    while not stop.is_set():
        if signal.sigtimedwait(_STOP_SIGNALS, 0.1) is not None:
            break
    stop.set()


#: Seconds the stop waits for the pool's workers to be killed and reaped (they take milliseconds).
RELEASE_WAIT = 20.0
#: Seconds the stop gives the web server (and the tabs' workers) in all before the process leaves.
STOP_WAIT = 2.0


def _shutdown(app, released: threading.Event) -> None:
    app.halt()  # the tabs told to stop, the pool's workers killed and reaped
    released.set()
    app.server.stop()


def stop_app(app) -> None:
    """Stop ``app`` from the main thread: the pool always, the web server within ``STOP_WAIT``."""
    t0 = time.monotonic()
    released = threading.Event()
    stopper = threading.Thread(target=_shutdown, args=(app, released), name="qsid-stop", daemon=True)
    stopper.start()
    released.wait(RELEASE_WAIT)
    stopper.join(max(0.0, STOP_WAIT - (time.monotonic() - t0)))
