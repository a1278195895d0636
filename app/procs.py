"""The process pool of ``qsid --workers`` and of the dashboard: loky's, its workers never outliving the program
(why loky, and why the parent watch: ``docs/architecture.rst``, "Worker processes")."""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable

import loky

__all__ = ["process_pool"]


def process_pool(workers: int, init: Callable[[], object] | None = None) -> loky.ProcessPoolExecutor:
    """``workers`` loky processes, all started, each having run ``init()`` (picklable) first; its public
    ``shutdown(kill_workers=True)`` kills and reaps them, busy, hung and stopped ones too."""
    pool = loky.ProcessPoolExecutor(workers, initializer=_worker_init, initargs=(os.getpid(), init))
    pool.submit(int).result()  # the first task starts every worker
    return pool


def _worker_init(parent: int, init: Callable[[], object] | None) -> None:
    """Ctrl-C and the stop signals are the program's; the worker exits within half a second of the program."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM, signal.SIGHUP})
    threading.Thread(target=_exit_with, args=(parent,), name="qsid-parent-watch", daemon=True).start()
    if init is not None:
        init()


def _exit_with(parent: int) -> None:
    while os.getppid() == parent:  # (the program gone, even by SIGKILL: the worker is re-parented)
        time.sleep(0.5)
    os._exit(0)
