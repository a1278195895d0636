"""Child processes that never outlive the program that started them (dashboard pool, ``qsid --workers``).

The standard library's private parts qsid relies on are all here, each with its reason:
``ProcessPoolExecutor._processes`` (its table of worker processes, to kill or count them) and
``multiprocessing.util._run_finalizers`` / ``resource_tracker._resource_tracker._stop`` (to release
a pool's semaphores at shutdown).
"""

from __future__ import annotations

import os
import signal
import threading
import time
from typing import Any

__all__ = ["end_with_parent", "kill_workers", "worker_pids", "release_ipc", "descendants", "kill_new_descendants"]


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


def _workers(ex: Any) -> list[Any]:
    """The worker processes of the ``ProcessPoolExecutor`` ``ex`` (none for another executor).

    The executor has no public list of them; its private ``_processes`` (pid -> Process) is that list.
    """
    return list((getattr(ex, "_processes", None) or {}).values())


def worker_pids(ex: Any) -> list[int]:
    """The process ids of the workers of the ``ProcessPoolExecutor`` ``ex`` (empty for another executor)."""
    return [int(p.pid) for p in _workers(ex) if p.pid is not None]


def kill_workers(ex: Any) -> None:
    """SIGKILL every worker process of the ``ProcessPoolExecutor`` ``ex`` (a stopped one too)."""
    for p in _workers(ex):
        try:
            p.kill()
        except Exception:
            pass


def descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (children, their children, ...), from Linux ``/proc`` (empty elsewhere)."""
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        try:
            tasks = os.listdir(f"/proc/{p}/task")
        except OSError:
            continue
        for task in tasks:
            try:
                with open(f"/proc/{p}/task/{task}/children") as f:
                    kids = [int(c) for c in f.read().split()]
            except OSError:
                continue
            out += kids
            todo += kids
    return out


def kill_new_descendants(before: set[int], keep: frozenset[int] | set[int] = frozenset()) -> list[int]:
    """SIGKILL every descendant of this process not in ``before`` or ``keep`` (e.g. a cluster interrupted
    while it started, whose processes no handle owns yet); returns their process ids.

    They are stopped first (SIGSTOP), and the tree is read again until no new process appears: a process
    killed while it forks would leave a child that no longer counts as ours (it prints a traceback when
    its parent's pipe closes under it). Stopped processes cannot fork, so the final SIGKILL gets them all.
    """
    found: list[int] = []
    for _ in range(50):  # each pass stops the processes the previous one found; a tree is rarely deeper than 3
        new = [p for p in descendants(os.getpid()) if p not in before and p not in keep and p not in found]
        if not new:
            break
        for p in new:
            try:
                os.kill(p, signal.SIGSTOP)
            except OSError:
                pass
        found += new
    for p in found:
        try:
            os.kill(p, signal.SIGKILL)
        except OSError:
            pass
    for p in found:  # reap our own children (grandchildren are reaped by whoever adopts them)
        try:
            os.waitpid(p, os.WNOHANG)
        except (ChildProcessError, OSError):
            pass
    return found


def release_ipc() -> None:
    """After a process pool is gone: unlink its semaphores and stop the resource tracker.

    Without this the tracker warns at exit of "leaked semaphore objects". There is no public call for
    either step: ``multiprocessing.util._run_finalizers(0)`` runs the semaphores' finalizers (which
    unlink and unregister them) and ``resource_tracker._resource_tracker._stop()`` ends the tracker
    process (nothing is left for it to warn of). Any failure is ignored: this runs at shutdown.
    """
    from multiprocessing import resource_tracker, util

    try:
        util._run_finalizers(0)  # type: ignore[attr-defined]
        resource_tracker._resource_tracker._stop()  # type: ignore[attr-defined]
    except Exception:
        pass
