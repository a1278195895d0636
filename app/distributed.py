"""Run sweeps on a dask.distributed cluster (``qsid sweep --dask SPEC``).

:func:`app.dask_cluster.make_executor` turns a ``--dask`` value (:func:`parse_dask_spec`) into a context
manager yielding a :class:`DaskExecutor`, a ``concurrent.futures.Executor`` the engine uses like any
other. Accepted values:

``local`` / ``local:N``
    Start a ``LocalCluster`` of N single-threaded worker processes on 127.0.0.1
    (``local`` = one per CPU core).
``tcp://HOST:PORT``
    Connect to a running ``dask scheduler`` (its workers must have the same qsid
    installed, e.g. ``pip install ".[distributed]"``).

What the wrapper adds to a plain ``client.get_executor()``:

* ``share(obj)``: the engine calls it (when present) for inputs every task needs
  -- the ~8 MB normalised data of a paper-scale sweep -- so they travel once per
  worker instead of once per task. The object becomes the result of one small
  task (``_identity(obj)``), copied once to every worker (``client.replicate``)
  so the tasks that depend on it spread evenly. Unlike ``client.scatter(broadcast=True)``
  this survives a lost worker: dask's active memory manager drops "superfluous"
  broadcast replicas, and a scattered object whose last copy dies cannot be
  recovered (seen in this repo's lost-worker test: every dependent task was
  cancelled), whereas a task result is simply recomputed. The engine itself never
  imports dask.
* No hang: a future waits in short slices and gives up with :class:`ClusterError`
  when the cluster has had no workers, or no scheduler connection, for
  ``stall_timeout`` seconds. When a worker dies mid-task the scheduler reruns
  its tasks on the other workers (up to dask's
  ``distributed.scheduler.allowed-failures``, default 3); tasks that raise are
  retried ``retries`` times.
* Errors are one line: a wrong address is a :class:`qsid_core.errors.ConfigError`
  after ``connect_timeout`` seconds; a missing ``distributed`` package says which
  extra to install.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import time
import uuid
import warnings

from app.daskspec import MAX_LOCAL_WORKERS, DaskSpec, parse_dask_spec
from qsid_core import ConfigError, QsidError

__all__ = ["ClusterError", "DaskSpec", "DaskExecutor", "parse_dask_spec", "MAX_LOCAL_WORKERS", "import_distributed"]


class ClusterError(QsidError):
    """The dask cluster failed during a run (no workers, scheduler gone, workers dying)."""


def import_distributed():
    try:
        import distributed
    except ImportError:
        raise ConfigError(
            "dask: the 'distributed' package is not installed; "
            'install the extra from the checkout: pip install ".[distributed]"'
        ) from None
    return distributed


class DaskExecutor(cf.Executor):
    """A ``concurrent.futures.Executor`` on a dask ``Client`` that shares big inputs and never hangs.

    Parameters
    ----------
    client : distributed.Client
        Not closed by :meth:`shutdown` (whoever made it closes it).
    retries : int
        Reruns of a task that raised (worker loss is handled by the scheduler).
    stall_timeout : float
        Seconds without any worker or without the scheduler before a waiting
        ``result()`` raises :class:`ClusterError`.
    share_data : bool
        ``False`` disables :meth:`share` (for measuring what it saves).
    """

    def __init__(self, client, retries: int = 1, stall_timeout: float = 60.0, share_data: bool = True):
        self.client = client
        self.retries = int(retries)
        self.stall_timeout = float(stall_timeout)
        self._futures: list = []
        self._shared: dict = {}
        self._closed = False
        if not share_data:
            self.share = None  # type: ignore[assignment]  # the engine then ships inputs with every task

    @property
    def address(self) -> str:
        return str(self.client.scheduler.address)

    @property
    def workers(self) -> int:
        """Workers the scheduler knows now (use ``tasks >= 2 * workers`` for an even load)."""
        return len(self.client.scheduler_info().get("workers", {}))

    def share(self, obj):
        """Make ``obj`` a dask future that tasks receive as ``obj`` itself; it travels once per worker.

        The same object shared twice gives the same future (kept while this executor lives).
        """
        key = id(obj)
        hit = self._shared.get(key)
        if hit is not None and hit[0] is obj:
            return hit[1]
        with warnings.catch_warnings():  # the object rides in the graph once, on purpose
            warnings.filterwarnings("ignore", message="Sending large graph")
            fut = self.client.submit(
                _identity, obj, pure=False, key=f"qsid-shared-{type(obj).__name__}-{uuid.uuid4().hex}"
            )
        try:
            end = time.monotonic() + self.stall_timeout
            while not fut.done():  # (distributed.wait needs a default client; this one is private)
                if time.monotonic() > end:
                    raise TimeoutError()
                time.sleep(0.005)
            if fut.status != "finished":
                fut.result()  # raises the task's error
            # a copy on every worker now, else the scheduler's data locality piles the tasks onto
            # the worker that holds it (measured: 3 of 4 tasks on one of 2 workers)
            self.client.replicate([fut])
        except (TimeoutError, OSError) as exc:
            raise ClusterError(
                f"dask: cannot place the shared data on a worker of {self.address} "
                f"({self._problem() or type(exc).__name__})"
            ) from None
        except Exception as exc:  # noqa: BLE001 -- e.g. a worker that cannot unpickle it
            raise ClusterError(f"dask: a worker could not take the shared data: {type(exc).__name__}: {exc}") from None
        self._shared[key] = (obj, fut)
        return fut

    def submit(self, fn, /, *args, **kwargs) -> cf.Future:
        if self._closed:
            raise RuntimeError("cannot submit to a DaskExecutor after shutdown")
        dfut = self.client.submit(fn, *args, pure=False, retries=self.retries, **kwargs)
        out = _WatchedFuture(self)
        self._futures.append(dfut)

        def copy(d, out=out):  # runs in a client thread when the dask future is done
            try:
                if d.status == "cancelled":
                    raise ClusterError(
                        f"dask cancelled a task: {self._problem() or 'its inputs were lost'} (scheduler {self.address})"
                    )
                res = d.result()
            except BaseException as exc:  # delivered through the future, as a pool would
                with contextlib.suppress(cf.InvalidStateError):
                    out.set_exception(_translate(exc, self.address))
                return
            with contextlib.suppress(cf.InvalidStateError):  # the watchdog may have given up first
                out.set_result(res)

        dfut.add_done_callback(copy)
        return out

    def _problem(self) -> str | None:
        """Why the cluster cannot make progress right now, or None."""
        if self.client.status != "running":
            return f"lost the connection to the dask scheduler at {self.address}"
        if not self.client.scheduler_info().get("workers"):
            return f"the dask scheduler at {self.address} has no workers"
        return None

    def wait(self, fut: cf.Future, timeout: float | None = None) -> None:
        """Wait for ``fut``; raise :class:`ClusterError` after ``stall_timeout`` s of a broken cluster."""
        end = None if timeout is None else time.monotonic() + timeout
        since = None
        while not fut.done():
            cf.wait([fut], timeout=0.25)
            if fut.done():
                return
            now = time.monotonic()
            if end is not None and now >= end:
                raise cf.TimeoutError()
            problem = self._problem()
            if problem is None:
                since = None
            elif since is None:
                since = now
            elif now - since > self.stall_timeout:
                with contextlib.suppress(cf.InvalidStateError):
                    fut.set_exception(ClusterError(f"{problem} for {self.stall_timeout:g} s; giving up"))

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        if self._closed:
            return
        self._closed = True
        pending = [f for f in self._futures if not f.done()]
        if pending and (cancel_futures or not wait):
            with contextlib.suppress(Exception):
                self.client.cancel(pending)
        self._futures.clear()
        self._shared.clear()


def _identity(obj):
    """The task behind :meth:`DaskExecutor.share` (recomputable if the worker holding it dies)."""
    return obj


class _WatchedFuture(cf.Future):
    """A future whose waits go through :meth:`DaskExecutor.wait` (no endless hang)."""

    def __init__(self, owner: DaskExecutor):
        super().__init__()
        self._owner = owner

    def result(self, timeout=None):
        self._owner.wait(self, timeout)
        return super().result(0)

    def exception(self, timeout=None):
        self._owner.wait(self, timeout)
        return super().exception(0)


def _translate(exc: BaseException, address: str) -> BaseException:
    """Dask's own failures as one-line :class:`ClusterError`; task errors pass through unchanged."""
    name = type(exc).__name__
    if name == "KilledWorker":
        return ClusterError(f"dask workers kept dying while running a task (out of memory?): {exc}")
    if name in ("FutureCancelledError", "CancelledError"):
        return ClusterError(f"dask lost a task (scheduler {address}): {exc}")
    if name == "CommClosedError" or isinstance(exc, ConnectionError):
        return ClusterError(f"dask: lost the connection to the scheduler {address} or a worker: {exc}")
    return exc
