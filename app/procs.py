"""The process pool of ``qsid --workers`` and of the dashboard: loky's, its workers never outliving the program
(why loky, measured against the standard library's pool and dask: ``docs/architecture.rst``, "Worker processes")."""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable

import loky

__all__ = ["process_pool"]


def process_pool(workers: int, init: Callable[[], object] | None = None) -> loky.ProcessPoolExecutor:
    """A :class:`loky.ProcessPoolExecutor` of ``workers`` processes, each running ``init()`` (picklable) first;
    returned once all have started (the first task starts them all). Its public ``shutdown(kill_workers=True)``
    SIGKILLs and reaps the workers, busy, hung and stopped ones too."""
    ex = loky.ProcessPoolExecutor(workers, initializer=_worker_init, initargs=(os.getpid(), init))
    ex.submit(int).result()
    return ex


def _worker_init(parent: int, init: Callable[[], object] | None) -> None:
    """In a worker: Ctrl-C and the stop signals are the program's (it stops the pool); the worker ends within half a
    second of the program, even one killed by SIGKILL (loky's do not: measured), also during a task (the numerical
    kernels release the GIL)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM, signal.SIGHUP})
    threading.Thread(target=_watch_parent, args=(parent,), name="qsid-parent-watch", daemon=True).start()
    if init is not None:
        init()


def _watch_parent(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(0.5)
    os._exit(0)
