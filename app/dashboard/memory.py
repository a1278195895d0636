"""Give freed memory back to the system (glibc keeps it otherwise: RSS only grows under many threads).

The dashboard allocates and frees many mid-sized blocks from many threads (tabs'
workers, viser's callback pool, the pool's result reader); glibc's per-thread
arenas keep what was freed. :func:`limit_arenas` caps their number before the
threads start and :func:`trim` (``malloc_trim(0)``) returns free pages; both do
nothing where glibc is not the allocator.
"""

from __future__ import annotations

import ctypes
import ctypes.util

__all__ = ["limit_arenas", "trim", "one_blas_thread"]

_M_ARENA_MAX = -8  # glibc's mallopt parameter number


def _libc():
    try:
        lib = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        lib.malloc_trim  # noqa: B018  (glibc only)
        return lib
    except (OSError, AttributeError):
        return None


_LIBC = _libc()


def limit_arenas(n: int = 2) -> bool:
    """At most ``n`` malloc arenas for threads started from now on; True if glibc took it."""
    return bool(_LIBC is not None and _LIBC.mallopt(_M_ARENA_MAX, int(n)))


def trim() -> bool:
    """Return the allocator's free pages to the system; True if any memory was released."""
    return bool(_LIBC is not None and _LIBC.malloc_trim(0))


def one_blas_thread() -> None:
    """Run BLAS with one thread in this whole process, from now on (the dashboard server and its workers).

    The engine's matrices are tiny and its parallelism comes from the tabs and the pool: extra BLAS threads
    only oversubscribe the cores. Set once, the engine's :func:`~qsid_core.studies.executors.single_threaded_blas`
    has nothing left to do on each call (it scanned every loaded library each time).
    """
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1, user_api="blas")  # not used as a context manager: the limit stays
