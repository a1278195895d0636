"""The tabs' process pool (:func:`app.procs.process_pool`) and :class:`Guarded`, the executor the engine sees: its
tasks abandoned for newer settings, failed when hung or when a worker dies (the pool then replaced).
The rules and why: ``docs/architecture.rst``, "Worker processes"."""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import BrokenExecutor, Executor, Future, InvalidStateError
from typing import Any

from loky import ProcessPoolExecutor
from loky.process_executor import ShutdownExecutorError

from app.procs import process_pool
from qsid_core import QsidError

from .lifecycle import one_blas_thread, trim

__all__ = ["Pool", "Guarded", "PoolFailure", "Superseded", "DEFAULT_TIMEOUT"]

DEFAULT_TIMEOUT = 60.0  #: seconds a pool task may run before its worker counts as hung
SUPERSEDED_GRACE = 3.0  #: seconds an abandoned task may keep its worker busy (tasks are far shorter)
TRIM_EVERY = 10.0  #: seconds between two ``malloc_trim`` of the server


class PoolFailure(QsidError):
    """A worker process of the pool ``executor`` died or hung; ``hint``: what to do if it happens again."""

    def __init__(self, message: str, executor: Executor | None = None, hint: str = "Change a setting to retry."):
        super().__init__(message)
        self.executor, self.hint = executor, hint


class Superseded(Exception):
    """The tab has newer settings: its pending pool work was abandoned."""


class Pool:
    """The tabs' process pool of ``workers`` processes (0: compute in-process), and its watchdog thread."""

    def __init__(self, workers: int, timeout: float = DEFAULT_TIMEOUT):
        self.workers, self.timeout, self.replacements, self._closed = max(0, int(workers)), float(timeout), 0, False
        self._lock, self._plock = threading.Lock(), threading.Lock()
        self._pending: list[list] = []  # [outer, inner, guard, running since] of each task not yet settled and ended
        self.current = self._new()
        threading.Thread(target=self._watchdog, name="qsid-pool-watch", daemon=True).start()

    def _new(self) -> ProcessPoolExecutor | None:
        try:  # BLAS runs one thread in the workers, as in the server (.lifecycle)
            return process_pool(self.workers, one_blas_thread) if self.workers else None
        except Exception as exc:  # e.g. no processes allowed here
            print(f"qsid-dashboard: no worker processes ({exc!r}); computing in-process", file=sys.stderr)
            return None

    def guarded(self, stop: Callable[[], bool] | None = None) -> Guarded | None:
        """An executor for one computation (None: compute in-process); ``stop()`` true abandons its tasks."""
        with self._lock:  # (a replacement under way: its new workers)
            ex = self.current
        return None if ex is None else Guarded(self, ex, stop or (lambda: False))

    def replace(self, failed: Any, counted: bool = True) -> bool:  # (Any: loky is untyped)
        """Kill ``failed``'s workers and start new ones if it is still the current pool (``counted``: a failure)."""
        with self._lock:
            if failed is not self.current or failed is None or self._closed:
                return False
            failed.shutdown(wait=False, kill_workers=True)
            self.current, self.replacements = self._new(), self.replacements + counted
            return True

    def release(self) -> None:
        """Fresh workers for the current ones: all the old ones held goes back to the system."""
        self.replace(self.current, counted=False)

    def shutdown(self) -> None:
        """Kill the workers and reap them."""
        self._closed = True
        with self._lock:
            ex, self.current = self.current, None
        if ex is not None:
            ex.shutdown(kill_workers=True)

    def _watchdog(self) -> None:
        last_trim = time.monotonic()
        while not self._closed:
            time.sleep(0.1)
            if time.monotonic() - last_trim > TRIM_EVERY:  # hand freed memory back (see .lifecycle)
                trim()
                last_trim = time.monotonic()
            with self._plock:  # an abandoned task still running stays watched until its worker is free
                self._pending = entries = [e for e in self._pending if not (e[0].done() and e[1].done())]
            for e in entries:
                outer, inner, guard, now = e[0], e[1], e[2], time.monotonic()
                e[3] = e[3] or (now if inner.running() else None)
                busy, stale = now - (e[3] or now), guard.stop()
                if stale or busy > self.timeout:  # abandoned at once (cancelled if queued), or hung
                    inner.cancel()
                    why = f"a worker process did not finish its task within {self.timeout:g} s (hung?)"
                    hint = "Try smaller settings, or start the server with a larger --task-timeout."
                    hung = PoolFailure(f"{why}; the pool was restarted", guard.executor, hint)
                    _settle(outer, Superseded() if stale else hung)
                if busy > (SUPERSEDED_GRACE if stale else self.timeout):
                    self.replace(guard.executor)


def _settle(fut: Future, exc: BaseException | None, result: object = None) -> None:
    with contextlib.suppress(InvalidStateError):  # settled already (by the watchdog or the worker)
        fut.set_exception(exc) if exc is not None else fut.set_result(result)


class Guarded(Executor):
    """The executor of one computation: tasks of one pool, watched for newer settings and time-outs."""

    def __init__(self, pool: Pool, executor: Executor, stop: Callable[[], bool]):
        self.pool, self.executor, self.stop = pool, executor, stop

    def submit(self, fn, /, *args, **kwargs) -> Future:
        if self.stop():
            raise Superseded()
        try:
            inner = self.executor.submit(fn, *args, **kwargs)
        except (RuntimeError, BrokenExecutor) as exc:  # the pool was shut down or broke meanwhile
            raise PoolFailure(f"the worker pool was restarted ({exc})", self.executor) from None
        outer: Future = Future()
        outer.set_running_or_notify_cancel()
        inner.add_done_callback(lambda f: self._copy(f, outer))
        with self.pool._plock:
            self.pool._pending.append([outer, inner, self, None])
        return outer

    def _copy(self, f: Future, outer: Future) -> None:
        exc = None if f.cancelled() else f.exception()
        if f.cancelled() or isinstance(exc, ShutdownExecutorError):  # abandoned, or its pool replaced under it
            exc = Superseded() if self.stop() else PoolFailure("the worker pool was restarted", self.executor)
        elif isinstance(exc, BrokenExecutor):
            exc = PoolFailure("a worker process died (killed or out of memory)", self.executor)
        _settle(outer, exc, None if exc is not None else f.result())
