"""Child processes that never outlive the program that started them (dashboard pool, ``qsid --workers``).

:class:`ProcessPool` is the process pool of both: a :class:`concurrent.futures.Executor` whose workers are
started with :class:`subprocess.Popen` (a fresh interpreter each, like multiprocessing's "spawn") and talk to
the pool over two pipes of their own, one pickled message at a time. It uses no multiprocessing machinery:
no queue, no semaphore, so no resource tracker process and nothing for one to warn about; its list of
worker processes is its own (:meth:`ProcessPool.pids`, :meth:`ProcessPool.kill`). A worker ends when its
task pipe closes (the pool shut down, or the program died: the kernel closes the pipe even after SIGKILL),
and at once through :func:`end_with_parent` when the program dies in the middle of a task.
"""

from __future__ import annotations

import os
import pickle
import queue
import signal
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import Executor, Future
from concurrent.futures.process import BrokenProcessPool
from typing import Any

__all__ = [
    "ProcessPool",
    "end_with_parent",
    "kill_workers",
    "worker_pids",
    "descendants",
    "kill_new_descendants",
    "resource_trackers",
]

_HEADER = struct.Struct("!Q")  # the length of one pickled message


def _send(fd: int, obj: object) -> None:
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    view = memoryview(_HEADER.pack(len(data)) + data)
    while view:
        view = view[os.write(fd, view) :]


def _read_exactly(fd: int, n: int) -> bytes | None:
    parts, left = [], n
    while left:
        chunk = os.read(fd, min(left, 1 << 20))
        if not chunk:  # the other end closed
            return None
        parts.append(chunk)
        left -= len(chunk)
    return b"".join(parts)


def _receive(fd: int) -> Any:
    """The next message of pipe ``fd``; raises EOFError when the other end closed."""
    head = _read_exactly(fd, _HEADER.size)
    body = None if head is None else _read_exactly(fd, _HEADER.unpack(head)[0])
    if body is None:
        raise EOFError
    return pickle.loads(body)


def _portable(exc: BaseException) -> BaseException:
    """``exc`` if it survives pickling, else a RuntimeError saying what it was."""
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:
        return RuntimeError(f"{type(exc).__name__}: {exc}")


def serve(tasks: int, results: int) -> None:
    """A worker's main loop: run each task read from pipe ``tasks``, write its outcome to pipe ``results``.

    The first message is the initializer ``(fn, args)`` (or None). Ends when ``tasks`` closes.
    """
    try:
        init = _receive(tasks)
        if init is not None:
            init[0](*init[1])
        while True:
            key, fn, args, kwargs = _receive(tasks)
            try:
                out: tuple = (key, True, fn(*args, **kwargs))
            except BaseException as exc:
                out = (key, False, _portable(exc))
            try:
                _send(results, out)
            except pickle.PicklingError as exc:
                _send(results, (key, False, RuntimeError(f"the task's result cannot be sent back: {exc}")))
    except EOFError:
        pass
    os._exit(0)


class _Worker:
    """One worker process, its two pipe ends and the thread that hands it tasks one at a time."""

    def __init__(self, pool: ProcessPool, initializer: Callable[..., object] | None, initargs: tuple):
        task_r, self.task_w = os.pipe()
        self.result_r, result_w = os.pipe()
        # the worker imports modules from the same places as this process (as multiprocessing's spawn does)
        code = f"import sys; sys.path[:] = {list(sys.path)!r}; from app.procs import serve; serve({task_r}, {result_w})"
        try:
            self.proc = subprocess.Popen(
                [sys.executable, "-c", code], pass_fds=(task_r, result_w), stdin=subprocess.DEVNULL
            )
        finally:
            os.close(task_r)
            os.close(result_w)
        self.pid = self.proc.pid
        self.extra: queue.SimpleQueue = queue.SimpleQueue()  # tasks for this worker only (ProcessPool.each)
        _send(self.task_w, None if initializer is None else (initializer, tuple(initargs)))
        self.thread = threading.Thread(target=pool._run_worker, args=(self,), name="qsid-proc-feed", daemon=True)

    def close(self) -> None:
        for fd in (self.task_w, self.result_r):
            try:
                os.close(fd)
            except OSError:
                pass


class ProcessPool(Executor):
    """``workers`` worker processes (see the module docstring); tasks are pickled as for ``ProcessPoolExecutor``.

    Parameters
    ----------
    workers : int
        Processes, started at once.
    initializer, initargs
        Run once in each worker before its first task.

    A worker that dies (killed, out of memory) breaks the pool, as in ``ProcessPoolExecutor``: its task and
    every pending one fail with :class:`~concurrent.futures.process.BrokenProcessPool`, and so does every
    later :meth:`submit`.
    """

    def __init__(self, workers: int, initializer: Callable[..., object] | None = None, initargs: tuple = ()):
        if workers < 1:
            raise ValueError(f"workers must be at least 1; got {workers}")
        self._queue: queue.SimpleQueue = queue.SimpleQueue()  # (future, fn, args, kwargs) or None (stop)
        self._lock = threading.Lock()
        self._broken: str | None = None
        self._shutdown = False
        self._workers: list[_Worker] = []
        try:
            for _ in range(workers):
                self._workers.append(_Worker(self, initializer, initargs))
        except BaseException:
            self.kill()
            raise
        for w in self._workers:
            w.thread.start()

    # ----- the pool's own process list ------------------------------------------------------------------------
    def pids(self) -> list[int]:
        """The process ids of the workers (dead ones included until the pool is shut down)."""
        return [w.pid for w in self._workers]

    def kill(self) -> None:
        """SIGKILL every worker (a stopped one too); their tasks fail with ``BrokenProcessPool``."""
        for w in self._workers:
            try:
                w.proc.kill()
            except OSError:
                pass

    # ----- Executor --------------------------------------------------------------------------------------------
    def submit(self, fn, /, *args, **kwargs) -> Future:
        with self._lock:
            if self._broken is not None:
                raise BrokenProcessPool(self._broken)
            if self._shutdown:
                raise RuntimeError("cannot schedule new futures after shutdown")
            fut: Future = Future()
            self._queue.put((fut, fn, args, kwargs))
        return fut

    def each(self, fn: Callable[[], object], timeout: float) -> list:
        """Run ``fn()`` once in every worker (ahead of queued tasks); returns the results in worker order."""
        if self._broken is not None:
            raise BrokenProcessPool(self._broken)
        futs = []
        for w in self._workers:
            fut: Future = Future()
            fut.set_running_or_notify_cancel()
            futs.append(fut)
            w.extra.put((fut, fn, (), {}))
        return [f.result(timeout=timeout) for f in futs]

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        with self._lock:
            self._shutdown = True
        if cancel_futures:
            self._cancel_queued()
        for _ in self._workers:
            self._queue.put(None)  # each feeder stops after the tasks queued before it
        if wait:
            for w in self._workers:
                w.thread.join()
                w.proc.wait()

    def _cancel_queued(self) -> None:
        while True:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                return
            if item is not None:
                item[0].cancel()

    def _break(self, why: str) -> None:
        with self._lock:
            if self._broken is None:
                self._broken = why
        while True:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                break
            if item is not None and item[0].set_running_or_notify_cancel():
                item[0].set_exception(BrokenProcessPool(why))
        self.kill()
        for _ in self._workers:
            self._queue.put(None)

    @property
    def broken(self) -> bool:
        """True once a worker died (every later :meth:`submit` raises ``BrokenProcessPool``)."""
        return self._broken is not None

    def _next(self, w: _Worker):
        """The next task of worker ``w``: one asked of it by :meth:`each`, else one of the shared queue; None
        when the worker died while idle (the pool is then broken at once, not at its next task)."""
        while True:
            try:
                return w.extra.get_nowait()
            except queue.Empty:
                pass
            try:
                return self._queue.get(timeout=0.1)
            except queue.Empty:
                if w.proc.poll() is not None and not self._shutdown:
                    self._break(f"a worker process (pid {w.pid}) died (killed or out of memory)")
                    return None

    def _run_worker(self, w: _Worker) -> None:
        """(one thread per worker) hand it tasks one at a time and settle their futures."""
        try:
            while True:
                item = self._next(w)
                if item is None or self._broken is not None:
                    break
                fut, fn, args, kwargs = item
                if not fut.running() and not fut.set_running_or_notify_cancel():
                    continue  # cancelled while queued
                try:
                    _send(w.task_w, (0, fn, args, kwargs))
                except (pickle.PicklingError, AttributeError, TypeError) as exc:
                    fut.set_exception(exc)
                    continue
                except OSError:
                    fut.set_exception(BrokenProcessPool("a worker process died (killed or out of memory)"))
                    self._break("a worker process died (killed or out of memory)")
                    break
                try:
                    _, ok, value = _receive(w.result_r)
                except (EOFError, OSError):
                    why = f"a worker process (pid {w.pid}) died (killed or out of memory)"
                    fut.set_exception(BrokenProcessPool(why))
                    self._break(why)
                    break
                if ok:
                    fut.set_result(value)
                else:
                    fut.set_exception(value)
        finally:
            w.close()  # the worker ends when its task pipe closes ...
            try:  # ... and is reaped here (no zombie)
                w.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:  # still busy with a task nobody waits for
                w.proc.kill()
                w.proc.wait()


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


def worker_pids(ex: Any) -> list[int]:
    """The process ids of the workers of ``ex`` if it is a :class:`ProcessPool` (empty for another executor)."""
    return ex.pids() if isinstance(ex, ProcessPool) else []


def kill_workers(ex: Any) -> None:
    """SIGKILL every worker process of ``ex`` if it is a :class:`ProcessPool` (a stopped one too)."""
    if isinstance(ex, ProcessPool):
        ex.kill()


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


def resource_trackers(pid: int) -> set[int]:
    """The multiprocessing resource trackers below process ``pid`` (started for processes that use
    multiprocessing, e.g. a local dask cluster's; each unlinks their semaphores once its program ends, so it
    is never killed with them). Found by the command line CPython starts them with (Linux ``/proc``)."""
    out = set()
    for p in descendants(pid):
        try:
            with open(f"/proc/{p}/cmdline", "rb") as f:
                if b"multiprocessing.resource_tracker" in f.read():
                    out.add(p)
        except OSError:
            continue
    return out
