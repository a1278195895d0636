"""Executors and BLAS limits shared by every staged computation of the engine."""

from __future__ import annotations

from concurrent.futures import Executor, Future

__all__ = ["InlineExecutor", "single_threaded_blas"]


class _DeferredFuture(Future):
    """A future whose work runs in the calling thread when its result is first asked for."""

    def __init__(self, fn, args, kwargs):
        super().__init__()
        self._call = (fn, args, kwargs)

    def _run(self) -> None:
        if self._call is not None:
            fn, args, kwargs = self._call
            self._call = None
            try:
                self.set_result(fn(*args, **kwargs))
            except BaseException as exc:  # delivered through the future, as a pool would
                self.set_exception(exc)

    def result(self, timeout=None):
        self._run()
        return super().result(timeout)

    def exception(self, timeout=None):
        self._run()
        return super().exception(timeout)


class InlineExecutor(Executor):
    """A ``concurrent.futures.Executor`` that runs tasks in the calling thread.

    Each task runs when its result is first asked for, so a caller that submits
    a whole stage and then reads results in order reports progress as it goes.
    """

    def submit(self, fn, /, *args, **kwargs) -> Future:  # type: ignore[override]
        return _DeferredFuture(fn, args, kwargs)


def single_threaded_blas():
    """Context manager limiting BLAS to one thread while the engine computes.

    The engine makes many tiny BLAS/LAPACK calls (5 x 5 Gram matrices, 4 x 4
    Riccati steps) and gets its parallelism from the executor; OpenBLAS threads
    are pure overhead for such sizes and oversubscribe the cores when tasks run
    side by side (measured: a 4 x 4 DARE took 24 ms with two busy BLAS threads,
    0.5 ms with one). The previous limits are restored on exit.
    """
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")
