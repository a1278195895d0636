"""Executors and BLAS limits shared by every staged computation of the engine."""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Callable
from concurrent.futures import Executor, Future
from contextlib import AbstractContextManager
from typing import Any

__all__ = ["InlineExecutor", "single_threaded_blas"]


class _DeferredFuture(Future[Any]):
    """A future whose work runs in the calling thread when its result is first asked for."""

    def __init__(self, fn: Callable[..., Any], args: tuple[Any, ...], kwargs: dict[str, Any]) -> None:
        super().__init__()
        self._call: tuple[Callable[..., Any], tuple[Any, ...], dict[str, Any]] | None = (fn, args, kwargs)

    def _run(self) -> None:
        if self._call is not None:
            fn, args, kwargs = self._call
            self._call = None
            try:
                self.set_result(fn(*args, **kwargs))
            except BaseException as exc:  # delivered through the future, as a pool would
                self.set_exception(exc)

    def result(self, timeout: float | None = None) -> Any:
        self._run()
        return super().result(timeout)

    def exception(self, timeout: float | None = None) -> BaseException | None:
        self._run()
        return super().exception(timeout)


class InlineExecutor(Executor):
    """A ``concurrent.futures.Executor`` that runs tasks in the calling thread.

    Each task runs when its result is first asked for, so a caller that submits
    a whole stage and then reads results in order reports progress as it goes.
    """

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future[Any]:
        return _DeferredFuture(fn, args, kwargs)


def single_threaded_blas() -> AbstractContextManager[object]:
    """Context manager limiting BLAS to one thread while the engine computes.

    The engine makes many tiny BLAS/LAPACK calls (5 x 5 Gram matrices, 4 x 4
    Riccati steps) and gets its parallelism from the executor; OpenBLAS threads
    are pure overhead for such sizes and oversubscribe the cores when tasks run
    side by side (measured: a 4 x 4 DARE took 24 ms with two busy BLAS threads,
    0.5 ms with one). The previous limits are restored on exit.

    Where every BLAS library already runs one thread (a program that set it once, as the dashboard
    server and its pool workers do) this does nothing: ``threadpool_limits`` scans every loaded library
    on each call (0.6-3 ms, paid about 30 times per dashboard change), while reading the thread counts
    through the libraries found once costs microseconds.
    """
    if all(lib.num_threads == 1 for lib in _blas_libraries()):
        return contextlib.nullcontext()
    from threadpoolctl import threadpool_limits

    limits: AbstractContextManager[object] = threadpool_limits(limits=1, user_api="blas")
    return limits


@functools.cache
def _blas_libraries() -> tuple[Any, ...]:
    """threadpoolctl's controllers of the process's BLAS libraries (numpy's and scipy's), found once."""
    import numpy  # noqa: F401
    import scipy.linalg  # noqa: F401  (scipy may bring a BLAS of its own)
    from threadpoolctl import ThreadpoolController

    return tuple(lib for lib in ThreadpoolController().lib_controllers if lib.user_api == "blas")
