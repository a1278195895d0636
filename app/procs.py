"""Child processes that never outlive the program that started them (dashboard pool, ``qsid --workers``)."""

from __future__ import annotations

import os
import signal
import threading
import time

__all__ = ["end_with_parent", "kill_workers"]


def end_with_parent(parent: int) -> None:
    """In a worker process: end at once when process ``parent`` (the one that started it) dies.

    Even SIGKILL of the parent (the out-of-memory killer), which no handler of the parent sees, ends
    the worker. Two mechanisms, because each misses a case of the other: ``PR_SET_PDEATHSIG`` (Linux)
    has the kernel send SIGKILL the moment the parent goes, but it fires when the *thread* that started
    the worker ends (so workers must be started from a thread that lives as long as the program) and
    it is not armed if the parent died before this call; a daemon thread comparing ``os.getppid()``
    with ``parent`` every half second covers that race and systems without ``prctl``.
    """
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL), 0, 0, 0)  # 1 = PR_SET_PDEATHSIG
    except (OSError, AttributeError):  # not Linux: the getppid check alone
        pass
    if os.getppid() != parent:  # the parent is gone already
        os._exit(0)
    threading.Thread(target=_watch_parent, args=(parent,), name="qsid-parent-watch", daemon=True).start()


def _watch_parent(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(0.5)
    os._exit(0)


def kill_workers(ex) -> None:
    """SIGKILL every worker process of the ``ProcessPoolExecutor`` ``ex`` (a stopped one too)."""
    procs = getattr(ex, "_processes", None) or {}  # ProcessPoolExecutor's own table of its workers
    for p in list(procs.values()):
        try:
            p.kill()
        except Exception:
            pass
