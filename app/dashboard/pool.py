"""The process pool every tab shares, and the guard each computation reaches it through.

Threading (see the list in :mod:`app.dashboard.session`):

- ``Pool._lock`` guards the swap of :attr:`Pool.current`. A pool is only ever replaced by
  :meth:`Pool.replace` *for the executor that failed*: a tab that saw the old pool break does not shut
  down the new one another tab already installed.
- one watchdog thread (``qsid-pool-watch``) looks at every pending task a few times a second: a task
  whose tab has newer settings is abandoned at once (:class:`Superseded`; queued work is cancelled; a
  worker still busy with it after ``SUPERSEDED_GRACE`` seconds is replaced with its pool), a task running
  longer than ``timeout`` seconds fails with :class:`PoolTimeout` and its pool is replaced (the hung worker
  is killed), a pool one of whose workers died is replaced at once, and one with a stopped worker
  (SIGSTOP, job control) as soon as it has work: a stopped worker never finishes its task. Tasks of the
  replaced pool that are not superseded fail with :class:`PoolBroken` (their tab retries once).

The engine only sees :class:`Guarded`, an executor whose futures settle in one of
those ways; everything else (results, exceptions) passes through unchanged.
"""

from __future__ import annotations

import functools
import gc
import os
import pickle
import shutil
import signal
import sys
import tempfile
import threading
import time
import weakref
from collections import OrderedDict
from collections.abc import Callable
from concurrent.futures import Future, InvalidStateError, ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool

from app.procs import ProcessPool, end_with_parent, kill_workers, worker_pids
from qsid_core import QsidError

from .memory import one_blas_thread, trim

__all__ = [
    "Pool",
    "Guarded",
    "PoolFailure",
    "PoolBroken",
    "PoolTimeout",
    "Superseded",
    "DEFAULT_TIMEOUT",
    "SHARE_BYTES",
]

#: Seconds between two ``malloc_trim`` calls of the watchdog.
TRIM_EVERY = 10.0
#: Seconds one pool task may run before its worker counts as hung (paper-scale tasks take a few seconds).
DEFAULT_TIMEOUT = 60.0
#: Seconds a task whose tab has newer settings may keep its worker busy before the pool is replaced, so the
#: newest settings never wait behind stale (or hung) work; ordinary tasks are chunks far shorter than this.
SUPERSEDED_GRACE = 3.0
#: Data every task of a pass needs and larger than this (bytes) goes to the workers once, through a file.
SHARE_BYTES = 1 << 20
#: How many shared objects the server keeps on disk, and each worker in memory.
SHARE_KEEP, WORKER_KEEP = 8, 2

_worker_shared: OrderedDict = OrderedDict()  # in a pool worker: file -> object, the last WORKER_KEEP


def _load_shared(path: str):
    """In a pool worker: the object the server shared as ``path`` (read once, then kept)."""
    obj = _worker_shared.get(path)
    if obj is None:
        try:
            with open(path, "rb") as f:
                obj = pickle.load(f)
        except FileNotFoundError:
            raise QsidError(
                "the data of this task were replaced meanwhile (many tabs changed their data at "
                "once); change a setting to retry"
            ) from None
        _worker_shared[path] = obj
        while len(_worker_shared) > WORKER_KEEP:
            _worker_shared.popitem(last=False)
    _worker_shared.move_to_end(path)
    return obj


def _release_worker() -> int:
    """In a pool worker: drop the data kept from earlier tasks and hand free pages back; returns the pid."""
    _worker_shared.clear()
    gc.collect()
    trim()
    return os.getpid()


def _same(obj: object) -> object:
    return obj


class _Shared:
    """Pickles as a file name; unpickles in the worker as the object itself (read once per worker)."""

    def __init__(self, path: str):
        self.path = path

    def __reduce__(self):
        return _load_shared, (self.path,)


class PoolFailure(QsidError):
    """A worker process of the shared pool died or hung; ``executor`` is the pool it happened in."""

    def __init__(self, message: str, executor=None):
        super().__init__(message)
        self.executor = executor


class PoolBroken(PoolFailure):
    """A worker process died (killed, out of memory, crashed)."""


class PoolTimeout(PoolFailure):
    """A task ran longer than the pool's per-task timeout."""


def twice_message(exc: PoolFailure) -> str:
    """What a tab says when its work failed in the pool twice in a row."""
    hint = (
        " Try smaller settings, or start the server with a larger --task-timeout."
        if isinstance(exc, PoolTimeout)
        else " Change a setting to retry."
    )
    return f"{exc} (twice).{hint}"


def _stopped(pid: int) -> bool:
    """True if process ``pid`` is stopped by a signal (Linux ``/proc``; False where that cannot be read)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            stat = f.read()
    except OSError:
        return False
    return stat[stat.rfind(b")") + 2 : stat.rfind(b")") + 3] == b"T"


def stopped_workers(ex) -> list[int]:
    """The process ids of the workers of :class:`~app.procs.ProcessPool` ``ex`` that are stopped (SIGSTOP)."""
    return [pid for pid in worker_pids(ex) if _stopped(pid)]


class Superseded(Exception):
    """The tab has newer settings: its pending pool work was abandoned."""


def _worker_init(parent: int | None = None) -> None:
    """Pool workers: Ctrl-C belongs to the server; the signal mask the server set is not inherited; BLAS runs
    one thread (as in the server, :func:`~app.dashboard.memory.one_blas_thread`); a worker
    ends by itself when the server dies, even by SIGKILL (see :func:`app.procs.end_with_parent`: this is
    why :class:`Pool` starts every worker from one thread that lives as long as the pool)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM, signal.SIGHUP})
    one_blas_thread()
    if parent is not None:
        end_with_parent(parent)


class Pool:
    """The tabs' shared process pool (``workers`` processes; 0 = compute in-process)."""

    def __init__(self, workers: int, timeout: float = DEFAULT_TIMEOUT):
        self.workers = max(0, int(workers))
        self.timeout = float(timeout)
        self.replacements = 0
        self._lock = threading.Lock()
        self._pending: list = []  # [outer, inner, guard, started-at or None]
        self._plock = threading.Lock()
        self._closed = False
        self._shared: OrderedDict = OrderedDict()  # id(obj) -> (weak ref, what tasks get); see share()
        self._share_dir: str | None = None
        self._slock = threading.Lock()
        # every worker process is started from this one thread, which lives as long as the pool (see
        # _worker_init: the parent-death signal fires when the thread that started a worker ends)
        self._spawner = ThreadPoolExecutor(1, thread_name_prefix="qsid-pool-spawn")
        self.current = self._new()
        self._watch = threading.Thread(target=self._watchdog, name="qsid-pool-watch", daemon=True)
        self._watch.start()

    def _new(self):
        if self.workers == 0:
            return None
        return self._spawner.submit(self._start).result()

    def _start(self):
        pool = None
        try:
            pool = ProcessPool(self.workers, initializer=_worker_init, initargs=(os.getpid(),))
            pool.each(os.getpid, timeout=120)  # every worker answers (imports done) before the pool is used
        except Exception as exc:  # e.g. no processes allowed here
            if pool is not None:
                pool.kill()
                pool.shutdown(wait=False, cancel_futures=True)
            print(
                f"qsid-dashboard: no worker processes ({type(exc).__name__}: {exc}); computing in-process",
                file=sys.stderr,
            )
            return None
        return pool

    def guarded(self, stop: Callable[[], bool] | None = None) -> Guarded | None:
        """An executor for one computation (None: compute in-process); ``stop()`` true abandons its tasks."""
        ex = self.current
        return None if ex is None else Guarded(self, ex, stop or (lambda: False))

    def share(self, obj):
        """What pool tasks get instead of ``obj``: the object itself if small, else a reference to a file
        written once (each worker reads it once), so a pass split into many short tasks does not send the
        data with every task. Only a weak reference to ``obj`` is kept (the cache decides how long it lives)."""
        with self._slock:
            hit = self._shared.get(id(obj))
            if hit is not None and hit[0]() is obj:
                self._shared.move_to_end(id(obj))
                return hit[1]
            data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
            if len(data) < SHARE_BYTES:
                return obj
            if self._share_dir is None:
                self._share_dir = tempfile.mkdtemp(prefix="qsid-share-")
            fd, path = tempfile.mkstemp(dir=self._share_dir, suffix=".pkl")
            with os.fdopen(fd, "wb") as f:
                f.write(data)
            arg = _Shared(path)
            ref: Callable[[], object]
            try:
                ref = weakref.ref(obj)
            except TypeError:  # not weakly referenceable: keep it while its file is kept
                ref = functools.partial(_same, obj)
            self._shared[id(obj)] = (ref, arg)
            while len(self._shared) > SHARE_KEEP:
                _, (_, old) = self._shared.popitem(last=False)
                try:
                    os.unlink(old.path)
                except OSError:
                    pass
            return arg

    def _drop_shared(self) -> None:
        """Forget every shared object and delete the server's files of them."""
        with self._slock:
            self._shared.clear()
            if self._share_dir is not None:
                shutil.rmtree(self._share_dir, ignore_errors=True)
                self._share_dir = None

    def each_worker(self, fn, timeout: float) -> int:
        """Run ``fn()`` (returns its worker's pid) in every worker of the current pool; returns how many ran it.

        Raises what ``fn`` or the pool raises (e.g. a timeout).
        """
        ex = self.current
        if ex is None:
            return 0
        return len(set(ex.each(fn, timeout)))

    def release(self, timeout: float = 30.0) -> int:
        """Forget every shared object (the server's files, each worker's copy) and have each worker hand its free
        pages back; returns how many workers did. Tasks that still need an object fail with a plain message."""
        self._drop_shared()
        try:
            return self.each_worker(_release_worker, timeout)
        except Exception:  # a pool being replaced or shut down meanwhile: its workers are going anyway
            return 0

    def replace(self, broken) -> bool:
        """Replace the pool if ``broken`` is still the current one (its workers are killed); True if replaced."""
        with self._lock:
            if broken is None or broken is not self.current or self._closed:
                return False
            self.current = self._new()
            self.replacements += 1
        kill_workers(broken)
        broken.shutdown(wait=False, cancel_futures=True)
        return True

    def shutdown(self) -> None:
        """Stop at once: kill the workers and reap them (milliseconds: nothing waits for their tasks)."""
        with self._lock:
            self._closed = True
            ex, self.current = self.current, None
        if ex is not None:
            kill_workers(ex)
            ex.shutdown(wait=True, cancel_futures=True)
        self._spawner.shutdown(wait=False)
        self._drop_shared()

    # ----- watchdog -------------------------------------------------------------------------
    def _track(self, entry: list) -> None:
        with self._plock:
            self._pending.append(entry)

    def _watchdog(self) -> None:
        last_trim = time.monotonic()
        while True:
            time.sleep(0.1)
            if time.monotonic() - last_trim > TRIM_EVERY:  # hand freed memory back (see .memory)
                trim()
                last_trim = time.monotonic()
            with self._plock:  # a superseded task still running stays watched until its worker is free
                entries = [e for e in self._pending if not (e[0].done() and e[1].done())]
                self._pending = entries
            self._check_stopped(entries)
            now = time.monotonic()
            for e in entries:
                outer, inner, guard = e[0], e[1], e[2]
                if e[3] is None and inner.running():
                    e[3] = now
                if guard.stop():
                    inner.cancel()
                    _settle(outer, exc=Superseded())
                    if e[3] is not None and now - e[3] > SUPERSEDED_GRACE:  # busy with work nobody wants
                        self.replace(guard.executor)
                    continue
                if e[3] is not None and now - e[3] > self.timeout:
                    _settle(
                        outer,
                        exc=PoolTimeout(
                            f"a worker process did not finish its task within {self.timeout:g} s (hung?); "
                            "it was stopped and the pool restarted",
                            guard.executor,
                        ),
                    )
                    self.replace(guard.executor)

    def _check_stopped(self, entries: list) -> None:
        """Replace the current pool at once if a worker died (even while idle: the next tab's work then finds a
        whole pool), or if it has unfinished work and a stopped worker."""
        ex = self.current
        if isinstance(ex, ProcessPool) and ex.broken:
            self.replace(ex)
            return
        if ex is None or not any(e[2].executor is ex and not e[1].done() for e in entries):
            return
        pids = stopped_workers(ex)
        if not pids:
            return
        exc = PoolBroken(f"a worker process was stopped (pid {pids[0]}); the pool was restarted", ex)
        for outer, inner, guard, _ in entries:
            if guard.executor is ex and not inner.done():
                _settle(outer, exc=Superseded() if guard.stop() else exc)
        self.replace(ex)


def _settle(fut: Future, result=None, exc: BaseException | None = None) -> None:
    try:
        if exc is not None:
            fut.set_exception(exc)
        else:
            fut.set_result(result)
    except InvalidStateError:  # already settled (by the watchdog or the worker)
        pass


class Guarded:
    """The executor one computation uses: tasks of one pool, watched for newer settings and time-outs."""

    def __init__(self, pool: Pool, executor, stop: Callable[[], bool]):
        self.pool, self.executor, self.stop = pool, executor, stop

    def submit(self, fn, /, *args, **kwargs) -> Future:
        if self.stop():
            raise Superseded()
        try:
            inner = self.executor.submit(fn, *args, **kwargs)
        except (RuntimeError, BrokenProcessPool) as exc:  # the pool was shut down or broke meanwhile
            raise PoolBroken(f"the worker pool was restarted ({exc})", self.executor) from None
        outer: Future = Future()
        outer.set_running_or_notify_cancel()

        def copy(f: Future) -> None:
            if f.cancelled():  # abandoned (newer settings), or its pool was replaced under it (retried)
                broken = PoolBroken("the worker pool was restarted", self.executor)
                _settle(outer, exc=Superseded() if self.stop() else broken)
                return
            exc = f.exception()
            if isinstance(exc, BrokenProcessPool):
                exc = PoolBroken("a worker process died (killed or out of memory)", self.executor)
            _settle(outer, f.result() if exc is None else None, exc)

        inner.add_done_callback(copy)
        self.pool._track([outer, inner, self, None])
        return outer

    def share(self, obj):
        """See :meth:`Pool.share` (the engine passes the data every task needs through this hook)."""
        return self.pool.share(obj)

    def map(self, fn, *iterables):
        futs = [self.submit(fn, *a) for a in zip(*iterables)]
        return (f.result() for f in futs)
