"""The tabs' process pool and :class:`Guarded`, the executor the engine sees; its watchdog abandons the tasks of a
tab with newer settings, fails hung ones, and replaces a pool that a hung or abandoned task keeps busy (the rules
and why: ``docs/architecture.rst``, "Worker processes")."""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import BrokenExecutor, Executor, Future, InvalidStateError
from typing import Any

from loky.process_executor import ShutdownExecutorError

from app.procs import process_pool
from qsid_core import QsidError

from .lifecycle import one_blas_thread

__all__ = ["Pool", "Guarded", "PoolFailure", "Superseded", "DEFAULT_TIMEOUT"]

DEFAULT_TIMEOUT = 60.0  #: seconds a task may run before its worker counts as hung
SUPERSEDED_GRACE = 3.0  #: seconds an abandoned task may keep its worker busy (tasks last a fraction of a second)


class PoolFailure(QsidError):
    """A worker of the pool ``executor`` died or hung; ``hint``: what to do if it happens again."""

    def __init__(self, message: str, executor: Any = None, hint: str = "Change a setting to retry."):
        super().__init__(message)
        self.executor, self.hint = executor, hint


class Superseded(Exception):
    """The tab has newer settings: its pending pool work was abandoned."""


class Pool:
    """The tabs' pool of ``workers`` processes (``current``; None: compute in-process) and its watchdog thread."""

    def __init__(self, workers: int, timeout: float = DEFAULT_TIMEOUT):
        self.workers, self.timeout, self.replacements = max(0, int(workers)), float(timeout), 0
        self._lock, self._closed = threading.Lock(), threading.Event()  # (the lock: one replacement at a time)
        self._tasks: deque[_Task] = deque()  # until loky's future and the engine's are both settled
        self.current = self._new()
        if self.current is not None:  # (a pool of none stays none)
            threading.Thread(target=self._watch, name="qsid-pool-watch", daemon=True).start()

    def _new(self) -> Any:  # (Any: loky is untyped)
        try:  # BLAS runs one thread in the workers, as in the server (.lifecycle)
            return process_pool(self.workers, one_blas_thread) if self.workers else None
        except Exception as exc:  # e.g. no processes allowed here
            print(f"qsid-dashboard: no worker processes ({exc!r}); computing in-process", file=sys.stderr)
            return None

    def guarded(self, stop: Callable[[], bool] = lambda: False) -> Guarded | None:
        """The executor of one computation (None: compute in-process); ``stop()`` true abandons its tasks."""
        executor = self.current
        return None if executor is None else Guarded(self, executor, stop)

    def replace(self, failed: Any, counted: bool = True, new: bool = True) -> bool:
        """Kill and reap ``failed``'s workers if it is still the current pool, then start ``new`` ones (``counted``:
        after a failure); False if it was replaced already."""
        with self._lock:
            if failed is None or failed is not self.current:
                return False
            failed.shutdown(kill_workers=True)
            self.current, self.replacements = self._new() if new else None, self.replacements + counted
            return True

    def release(self) -> None:
        """Fresh workers for the current ones: all the old ones held goes back to the system."""
        self.replace(self.current, counted=False)

    def shutdown(self) -> None:
        """Kill the workers and reap them; the watchdog ends."""
        self._closed.set()
        self.replace(self.current, counted=False, new=False)

    def _watch(self) -> None:
        while not self._closed.wait(0.1):
            for _ in range(len(self._tasks)):  # each task once (Guarded.submit appends meanwhile)
                task, now = self._tasks.popleft(), time.monotonic()
                if task.done() and task.inner.done():  # (an abandoned task stays watched until its worker is free)
                    continue
                self._tasks.append(task)
                task.started = task.started or (now if task.inner.running() else None)
                busy, stale, executor = now - (task.started or now), task.guard.stop(), task.guard.executor
                if stale or busy > self.timeout:  # abandoned at once (dropped if still queued), or hung
                    why = f"a worker process did not finish its task within {self.timeout:g} s (hung?)"
                    hint = "Try smaller settings, or start the server with a larger --task-timeout."
                    task.settle(
                        Superseded() if stale else PoolFailure(f"{why}; the pool was restarted", executor, hint)
                    )
                    task.inner.cancel()
                if busy > (SUPERSEDED_GRACE if stale else self.timeout):
                    self.replace(executor)


class _Task(Future):
    """The engine's future of one pool task: settled from loky's (``inner``), or earlier by the watchdog."""

    def __init__(self, guard: Guarded, inner: Future):
        super().__init__()
        self.set_running_or_notify_cancel()
        self.guard, self.inner = guard, inner
        self.started: float | None = None  # when inner was first seen running
        inner.add_done_callback(self._copy)

    def settle(self, exc: BaseException | None, result: object = None) -> None:
        with contextlib.suppress(InvalidStateError):  # settled already (by the watchdog, or from loky's future)
            self.set_exception(exc) if exc is not None else self.set_result(result)

    def _copy(self, inner: Future) -> None:
        if inner.cancelled():  # by the watchdog, which settled this one first
            return
        exc = inner.exception()
        died = isinstance(exc, BrokenExecutor)
        if died or isinstance(exc, ShutdownExecutorError):  # a worker died, or the pool was replaced under the task
            why = "a worker process died (killed or out of memory)" if died else "the worker pool was restarted"
            exc = PoolFailure(why, self.guard.executor)
        self.settle(exc, None if exc is not None else inner.result())


class Guarded(Executor):
    """The executor of one computation: its tasks run in one pool's workers, watched by the pool's watchdog."""

    def __init__(self, pool: Pool, executor: Any, stop: Callable[[], bool]):
        self.pool, self.executor, self.stop = pool, executor, stop

    def submit(self, fn, /, *args, **kwargs) -> Future:
        if self.stop():
            raise Superseded()
        try:
            task = _Task(self, self.executor.submit(fn, *args, **kwargs))
        except RuntimeError as exc:  # (BrokenExecutor, ShutdownExecutorError) the pool broke or was replaced
            raise PoolFailure(f"the worker pool was restarted ({exc})", self.executor) from None
        self.pool._tasks.append(task)
        return task
