"""Work under way, by cache key: several threads that ask for the same stage result wait for one computation.

A mapping shared by many experiments (the dashboard's browser tabs) that carries a :class:`Flights` as its
``flights`` attribute lets them join each other's work: the first thread to ask for a key *owns* it and computes
it; every later thread waits for that result instead of computing it again. When the owner fails (bad settings,
a worker that died, a stop), its waiters compute the result themselves, so a failure is never shared, only a
success.

Stage results form a directed acyclic graph (loops need models, models need moments, moments need data), and a
thread owns a key only while it computes it, so no two threads can wait for each other.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Hashable, Iterable, MutableMapping
from concurrent.futures import Future
from typing import Any, TypeVar, cast

__all__ = ["Flights", "flights_of", "memo_joined"]

T = TypeVar("T")


class Flights:
    """The keys being computed now, each with the future its waiters wait on.

    Thread-safe. :meth:`claim` hands each key to exactly one owner; the owner ends it with :meth:`land`
    (a result) or :meth:`abort` (a failure, which sends the waiters off to compute it themselves).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._running: dict[Hashable, Future[Any]] = {}
        #: how many waits were answered by another thread's computation (a measure, for tests and benchmarks)
        self.joined = 0

    def claim(self, keys: Iterable[Hashable]) -> tuple[list[Hashable], dict[Hashable, Future[Any]]]:
        """``(mine, theirs)``: the keys the caller now owns and must end, and the futures of keys owned by others."""
        mine: list[Hashable] = []
        theirs: dict[Hashable, Future[Any]] = {}
        with self._lock:
            for key in keys:
                running = self._running.get(key)
                if running is None:
                    self._running[key] = Future()
                    mine.append(key)
                else:
                    theirs[key] = running
        return mine, theirs

    def land(self, key: Hashable, value: object) -> None:
        """End the owned ``key`` with its result: every waiter gets ``value``."""
        with self._lock:
            fut = self._running.pop(key, None)
        if fut is not None:
            fut.set_result(value)

    def abort(self, keys: Iterable[Hashable]) -> None:
        """End the owned ``keys`` without a result: their waiters compute them themselves."""
        with self._lock:
            futs = [f for f in (self._running.pop(k, None) for k in keys) if f is not None]
        for fut in futs:
            fut.set_exception(_Aborted())

    def wait(self, fut: Future[Any]) -> tuple[bool, object]:
        """``(True, result)`` of another thread's computation, or ``(False, None)`` when its owner failed."""
        try:
            value = fut.result()
        except _Aborted:
            return False, None
        with self._lock:
            self.joined += 1
        return True, value

    def __len__(self) -> int:
        with self._lock:
            return len(self._running)


def _stored_meanwhile(mapping: MutableMapping[Any, object], key: Hashable, make: Callable[[], T]) -> T:
    """``mapping[key]`` if an owner stored it between the caller's look and its claim, else ``make()``."""
    try:
        return cast(T, mapping[key])
    except KeyError:
        return make()


class _Aborted(Exception):
    """The owner of a key ended without its result."""


def flights_of(mapping: object) -> Flights | None:
    """The :class:`Flights` a shared mapping carries as its ``flights`` attribute, else None."""
    flights = getattr(mapping, "flights", None)
    return flights if isinstance(flights, Flights) else None


def memo_joined(mapping: MutableMapping[Any, object], key: Hashable, make: Callable[[], T]) -> T:
    """``mapping[key]``; else the result of the thread computing it now, if any; else ``make()``, stored.

    The mapping may be bounded and drop any entry at any moment, so the value is returned from here, never
    read back after storing.
    """
    flights = flights_of(mapping)
    while True:
        try:
            return cast(T, mapping[key])  # stored under this key by the same stage: a T
        except KeyError:
            pass
        if flights is None:
            value = make()
            mapping[key] = value
            return value
        mine, theirs = flights.claim([key])
        if theirs:
            ok, got = flights.wait(theirs[key])
            if ok:
                return cast(T, got)
            continue  # its owner failed: try again, most likely as the owner
        try:
            value = _stored_meanwhile(mapping, key, make)
        except BaseException:
            flights.abort(mine)
            raise
        mapping[key] = value
        flights.land(key, value)
        return value
