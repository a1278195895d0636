"""The bounded, thread-safe cache that every browser tab passes to the engine.

Each tab's :class:`~qsid_core.studies.experiment.Experiment` gets ``cache=`` the app's one
:class:`SharedCache`, so tabs with equal settings share data, moments, models and
closed loops, and memory stays bounded. Its ``flights`` (:class:`~qsid_core.studies.Flights`) let a tab
join a result another tab is computing now instead of computing it again.
"""

from __future__ import annotations

import dataclasses
import sys
import threading
from collections import OrderedDict
from collections.abc import Callable, MutableMapping
from typing import Any

import numpy as np

from qsid_core.studies import Flights

__all__ = ["SharedCache", "DEFAULT_MB"]

#: Default budget (MB). It holds one paper-scale tab's results (~94 MB) or the changes of a class; measured with
#: 30 tabs of a class (benchmarks/bench_class.py): 256 MB took server + workers to ~1.08 GB, 128 MB to ~0.95 GB.
DEFAULT_MB = 128


def _nbytes(obj, depth: int = 0) -> int:
    """Memory held by a cached stage result: array data AND the Python objects around it.

    Many entries are small (a few realizations of 3 x 4 Gram matrices): there
    the object overhead (an array's header is ~112 bytes, a dataclass instance
    with its ``__dict__`` several hundred) outweighs the numbers, and counting
    only ``nbytes`` let the cache hold several times its budget.
    """
    if isinstance(obj, np.ndarray):
        return int(obj.nbytes) + 112  # a view keeps its base alive: counted as if it owned its data
    if isinstance(obj, (str, bytes, int, float, bool, type(None))):
        return sys.getsizeof(obj)
    if depth > 6:
        return 64
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return (
            64
            + sys.getsizeof(getattr(obj, "__dict__", {}))
            + sum(_nbytes(getattr(obj, f.name), depth + 1) for f in dataclasses.fields(obj))
        )
    if isinstance(obj, (list, tuple, set, frozenset)):
        return sys.getsizeof(obj) + sum(_nbytes(x, depth + 1) for x in obj)
    if isinstance(obj, dict):
        return sys.getsizeof(obj) + sum(_nbytes(k, depth + 1) + _nbytes(x, depth + 1) for k, x in obj.items())
    return max(64, sys.getsizeof(obj))


class SharedCache(MutableMapping):
    """A thread-safe LRU mapping bounded by an estimate of its memory (default :data:`DEFAULT_MB` MB; ``size``
    estimates one entry's bytes).

    Passed as ``Experiment(..., cache=shared)`` by every browser tab, so equal
    settings share the data, moments, models and closed loops. The least
    recently used entries are dropped first; the newest ``keep`` entries are never
    dropped (a tab usually reads its newest results again at once). Any other entry may
    go while a tab computes: the engine never reads back what it stored.
    """

    def __init__(self, max_bytes: int = DEFAULT_MB * 2**20, keep: int = 64, size: Callable[[Any], int] = _nbytes):
        self.max_bytes = int(max_bytes)
        self.keep = int(keep)
        self._measure = size  # an entry's estimated bytes (default: arrays and the Python objects around them)
        self._d: OrderedDict = OrderedDict()
        self._size: dict = {}
        self._total = 0
        self._lock = threading.Lock()  # viser callbacks, tab workers and helper threads read and write at once
        self.hits = 0
        self.misses = 0
        #: stage results being computed now: a tab asking for one waits for it instead of computing it again
        self.flights = Flights()

    def __getitem__(self, key):
        with self._lock:
            try:
                val = self._d[key]
            except KeyError:
                self.misses += 1
                raise
            self._d.move_to_end(key)
            self.hits += 1
            return val

    def __contains__(self, key) -> bool:
        with self._lock:
            return key in self._d

    def __setitem__(self, key, value) -> None:
        size = self._measure(value)
        with self._lock:
            if key in self._d:
                self._total -= self._size.pop(key)
                del self._d[key]
            self._d[key] = value
            self._size[key] = size
            self._total += size
            while self._total > self.max_bytes and len(self._d) > self.keep:
                old, _ = self._d.popitem(last=False)
                self._total -= self._size.pop(old)

    def __delitem__(self, key) -> None:
        with self._lock:
            del self._d[key]
            self._total -= self._size.pop(key)

    def clear(self) -> None:
        """Drop every entry."""
        with self._lock:
            self._d.clear()
            self._size.clear()
            self._total = 0

    def __iter__(self):
        with self._lock:
            return iter(list(self._d))

    def __len__(self) -> int:
        with self._lock:
            return len(self._d)

    @property
    def nbytes(self) -> int:
        """Estimated memory held."""
        return self._total

    def kinds(self) -> dict:
        """How many entries of each stage (``"data"``, ``"mom"``, ``"loops"``, ...) are held."""
        with self._lock:
            out: dict = {}
            for k in self._d:
                out[k[0]] = out.get(k[0], 0) + 1
            return out
