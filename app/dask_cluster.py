"""The dask cluster behind ``--dask SPEC``: a local one started here or a running scheduler reached, the
workers checked (the same qsid everywhere), and :func:`make_executor`, the context manager that yields a
:class:`~app.distributed.DaskExecutor` on it and leaves no cluster process behind, interrupted or not."""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import warnings
from collections.abc import Callable, Iterator

from app.distributed import ClusterError, DaskExecutor, import_distributed, parse_dask_spec
from app.stop import check_stopped
from qsid_core import ConfigError

__all__ = ["make_executor"]


def _check_workers(client) -> None:
    """Every worker must import the same qsid_core (same numbers); numpy differences are warned about."""

    def probe():  # nested: cloudpickle ships it by value
        import numpy

        try:
            import app.distributed  # noqa: F401 -- holds the share() task
            import qsid_core
        except Exception as exc:  # noqa: BLE001 -- reported to the user
            return ("error", f"{type(exc).__name__}: {exc}", numpy.__version__)
        return ("ok", qsid_core.__version__, numpy.__version__)

    import numpy

    import qsid_core

    for worker, (status, ver, npver) in sorted(client.run(probe).items()):
        if status != "ok":
            raise ClusterError(
                f"dask worker {worker} cannot import qsid ({ver}); install qsid on every "
                'worker (pip install ".[distributed]" from the checkout) or put it on the '
                "workers' PYTHONPATH"
            )
        if ver != qsid_core.__version__:
            raise ClusterError(
                f"dask worker {worker} has qsid {ver}, this client {qsid_core.__version__}; "
                "install the same version everywhere"
            )
        if npver != numpy.__version__:
            warnings.warn(
                f"dask worker {worker} has numpy {npver}, this client {numpy.__version__}: "
                "results may differ from an in-process run in the last bits",
                stacklevel=2,
            )


@contextlib.contextmanager
def make_executor(
    spec: str,
    progress: Callable[[str], None] | None = None,
    *,
    connect_timeout: float = 5.0,
    worker_timeout: float = 60.0,
    stall_timeout: float = 60.0,
    retries: int = 1,
    share_data: bool = True,
    quiet: bool = True,
) -> Iterator[DaskExecutor]:
    """Context manager: a :class:`DaskExecutor` on the cluster ``spec`` names, closed on exit.

    Parameters
    ----------
    spec : str
        ``'local'``, ``'local:N'`` or ``'tcp://HOST:PORT'`` (see :func:`parse_dask_spec`).
    progress : callable(str), optional
        Receives one line of text per step (starting, connected, workers).
    connect_timeout : float
        Seconds to reach the scheduler before a :class:`ConfigError`.
    worker_timeout : float
        Seconds to wait for the first worker of a remote scheduler.
    stall_timeout, retries, share_data
        Passed to :class:`DaskExecutor`.
    quiet : bool
        Silence dask's own log output (tracebacks of lost connections) while the
        context is open; failures still arrive as :class:`ClusterError`.
    """
    parsed = parse_dask_spec(spec)
    import_distributed()

    say = progress or (lambda _msg: None)
    before = set(descendants(os.getpid())) if parsed.local else None
    clusters = _clusters()
    try:
        with _cluster_executor(
            parsed, say, connect_timeout, worker_timeout, stall_timeout, retries, share_data, quiet
        ) as ex:
            yield ex
    except BaseException as exc:  # interrupted (a signal) at any moment, start-up included: no cluster process left
        if before is not None:
            kill_new_descendants(before, keep=resource_trackers(os.getpid()))
        if isinstance(exc, KeyboardInterrupt):
            # the program is stopping: the cluster's half-started tasks end with "Task exception was never
            # retrieved" tracebacks from asyncio and dask when they are collected; the interrupt says it all
            for name in ("asyncio", "distributed", "tornado"):
                logging.getLogger(name).setLevel(logging.CRITICAL + 1)
            # a cluster interrupted while it started has no handle here; its processes are gone, and dask's own
            # exit hook would only fail to close it (an "Exception ignored in atexit callback" traceback)
            for cluster in _clusters() - clusters:
                cluster.shutdown_on_close = False
        raise


def _clusters() -> set:
    """dask's own registry of the clusters this program started (closed at exit by dask unless told not to)."""
    from distributed.deploy.spec import SpecCluster

    return set(SpecCluster._instances)


@contextlib.contextmanager
def _cluster_executor(parsed, say, connect_timeout, worker_timeout, stall_timeout, retries, share_data, quiet):
    from distributed import Client, LocalCluster

    cluster = None
    with contextlib.ExitStack() as stack:
        if quiet:  # dask logs lost connections with tracebacks; the run reports them as one ClusterError line
            # (its tornado/asyncio callbacks too: an interrupt during start-up fails some of them)
            for name in ("distributed", "tornado", "asyncio"):
                log = logging.getLogger(name)
                stack.callback(log.setLevel, log.level)
                log.setLevel(logging.CRITICAL)
        if parsed.local:
            say(f"dask: starting a local cluster of {parsed.workers} worker process(es) on 127.0.0.1")
            with warnings.catch_warnings():  # its small HTTP server moves off a busy port 8787: not news
                warnings.filterwarnings("ignore", message=r"Port \d+ is already in use")
                cluster = stack.enter_context(
                    LocalCluster(
                        n_workers=parsed.workers,
                        threads_per_worker=1,
                        processes=True,
                        host="127.0.0.1",
                        dashboard_address=None,
                        silence_logs=logging.ERROR,
                    )
                )
            check_stopped()  # a stop signal during the start-up, whose interrupt dask caught
            address = cluster.scheduler_address
        else:
            address = parsed.address
        try:
            client = Client(cluster if cluster is not None else address, timeout=connect_timeout, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise ConfigError(
                f"dask: cannot reach a scheduler at {address} within {connect_timeout:g} s "
                f"({type(exc).__name__}); check the address and that 'dask scheduler' runs "
                "there"
            ) from None
        stack.callback(client.close)
        try:
            client.wait_for_workers(1, timeout=worker_timeout)
        except (TimeoutError, OSError):
            raise ClusterError(
                f"dask: the scheduler at {address} has no workers after {worker_timeout:g} s; "
                f"start some with 'dask worker {address}'"
            ) from None
        check_stopped()
        _check_workers(client)
        nw = len(client.scheduler_info().get("workers", {}))
        say(f"dask: connected to {address} ({nw} worker(s))")
        executor = DaskExecutor(client, retries=retries, stall_timeout=stall_timeout, share_data=share_data)
        stack.callback(executor.shutdown, wait=False, cancel_futures=True)
        yield executor


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
