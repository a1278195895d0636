"""Limit the threads of the OpenBLAS libraries loaded in this process (numpy's and scipy's).

Used as a process-pool initializer: the engine's tasks make thousands of tiny
BLAS/LAPACK calls (5 x 5 Grams, 3 x 3 DAREs), for which OpenBLAS threads are pure
overhead, and two worker processes x two BLAS threads each oversubscribe a
2-core machine. Linux only (reads /proc/self/maps); elsewhere it does nothing.
"""

from __future__ import annotations

import ctypes

_SETTERS = ("scipy_openblas_set_num_threads64_", "scipy_openblas_set_num_threads", "openblas_set_num_threads64_",
            "openblas_set_num_threads")
_GETTERS = ("scipy_openblas_get_num_threads64_", "scipy_openblas_get_num_threads", "openblas_get_num_threads64_",
            "openblas_get_num_threads")


def loaded_openblas() -> list[str]:
    """Paths of the OpenBLAS shared libraries mapped into this process."""
    try:
        with open("/proc/self/maps") as fh:
            paths = {line.split()[-1] for line in fh if "openblas" in line.lower() and "/" in line}
    except OSError:
        return []
    return sorted(paths)


def _call(names, *args):
    out = {}
    for path in loaded_openblas():
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for nm in names:
            fn = getattr(lib, nm, None)
            if fn is not None:
                out[path] = fn(*args)
                break
    return out


def set_blas_threads(n: int = 1) -> int:
    """Set every loaded OpenBLAS to ``n`` threads; returns how many libraries were set."""
    import numpy  # noqa: F401  (make sure numpy's and scipy's BLAS are loaded first)
    import scipy.linalg  # noqa: F401

    return len(_call(_SETTERS, ctypes.c_int(int(n))))


def blas_threads() -> dict:
    """Thread count of each loaded OpenBLAS (library file name -> threads)."""
    return {p.rsplit("/", 1)[-1]: int(v) for p, v in _call(_GETTERS).items()}
