"""The process pool of ``qsid --workers`` and of the dashboard: loky, its workers never outliving the program.

Why loky (measured against the standard library's pool and dask): ``docs/architecture.rst``, "Worker processes".
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable
from concurrent.futures import Executor

import loky

__all__ = ["process_pool", "stop"]


def process_pool(workers: int, init: Callable[[], object] | None = None) -> Executor:
    """A :class:`loky.ProcessPoolExecutor` of ``workers`` processes, each running ``init()`` (picklable) first;
    returned once they have started (the first task, which starts them all, answered)."""
    ex = loky.ProcessPoolExecutor(workers, initializer=_worker_init, initargs=(os.getpid(), init))
    ex.submit(int).result()
    return ex


def stop(ex: Executor, kill: bool = False, wait: bool = True) -> None:
    """Shut ``ex`` down; ``kill``: SIGKILL the workers of a :func:`process_pool` (busy, hung or stopped ones too),
    or cancel the queued tasks of another executor, instead of waiting for them."""
    if isinstance(ex, loky.ProcessPoolExecutor):
        ex.shutdown(wait=wait, kill_workers=kill)
    else:
        ex.shutdown(wait=wait, cancel_futures=kill)


def _worker_init(parent: int, init: Callable[[], object] | None) -> None:
    """In a worker: Ctrl-C and the stop signals belong to the program (which stops the pool); the worker ends within
    half a second of the program, even one killed by SIGKILL, which no handler sees (the numerical kernels release
    the GIL, so the check runs during a task too)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM, signal.SIGHUP})
    threading.Thread(target=_watch_parent, args=(parent,), name="qsid-parent-watch", daemon=True).start()
    if init is not None:
        init()


def _watch_parent(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(0.5)
    os._exit(0)
