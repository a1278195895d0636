"""Back-pressure: what one tab may queue, how tabs share the compute slots, and how big pool tasks are.

A hand-made client can send tens of thousands of changes a second. viser runs a
plain ``def`` input callback by submitting it to its one shared thread pool,
once per message: under a flood that queue grew without bound, and a new tab's
connect callback (queued behind it) did not run for more than 30 s.

- :class:`TabCallbacks` replaces viser's thread pool *for one tab's panel*
  (``client.gui``): a callback marked :func:`inline` (it only marks the tab
  dirty) runs at once where the message arrives; any other callback runs in the
  tab's own callback thread, and while one call of it is queued a newer one
  only replaces its arguments (only the newest matters). A tab can therefore
  queue at most one call per callback, whatever it sends.
- :class:`FairSlots`: the compute slots are handed out first come, first served,
  so a tab that keeps computing cannot take a slot back before a waiting tab; a cheap
  turn (only drawing left: a word length change) goes first, and has a slot of its own.
- :data:`READ_BYTES`: the event loop reads at most this much of one tab's socket at a time
  (:func:`app.dashboard.viserfix.limit_reads`). viser turns every message read into tasks before the
  loop does anything else; one 256 KiB read of a flooding client (thousands of messages) made every
  loop turn last ~1 s, and a new tab's handshake needs several turns (it took 5-11 s during a flood).
- (how many pool tasks a quantization pass is split into, so that each lasts a fraction of a second, is the
  engine's: :func:`qsid_core.studies.task_count`)
"""

from __future__ import annotations

import contextlib
import threading
from collections import OrderedDict, deque
from collections.abc import Callable
from concurrent.futures import Future

__all__ = [
    "inline",
    "TabCallbacks",
    "FairSlots",
    "READ_BYTES",
]

#: Bytes the event loop reads from one tab's socket per turn (asyncio's default: 256 KiB); ~40 changes.
READ_BYTES = 4096


def inline(fn: Callable) -> Callable:
    """Mark an input callback as cheap (it only marks the tab dirty): it runs where the message arrives."""
    fn.__dict__["qsid_inline"] = True
    return fn


def _done(result=None) -> Future:
    f: Future = Future()
    f.set_result(result)
    return f


class TabCallbacks:
    """The executor of one tab's panel callbacks (installed as ``client.gui._thread_executor``).

    ``submit(fn, *args)`` runs an :func:`inline` callback at once; any other callback
    is queued for the tab's callback thread, at most once: a newer call of a queued
    callback replaces its arguments. Every callback's errors are printed (as viser does).
    """

    def __init__(self, name: str):
        self.name = name
        self._lock = threading.Condition()
        self._queue: OrderedDict = OrderedDict()  # fn -> [args, kwargs, future]
        self._closed = False
        self._thread: threading.Thread | None = None
        self.coalesced = 0  #: calls merged into a queued one (for tests and benchmarks)

    def submit(self, fn: Callable, /, *args, **kwargs) -> Future:
        if getattr(fn, "qsid_inline", False):
            fut: Future = Future()
            try:
                fut.set_result(fn(*args, **kwargs))
            except Exception as exc:  # reported by viser's done-callback
                fut.set_exception(exc)
            return fut
        with self._lock:
            if self._closed:
                return _done()
            entry = self._queue.get(fn)
            if entry is not None:  # already queued: only the newest arguments matter
                entry[0], entry[1] = args, kwargs
                self.coalesced += 1
                return entry[2]
            fut = Future()
            self._queue[fn] = [args, kwargs, fut]
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name=f"qsid-callbacks-{self.name}", daemon=True)
                self._thread.start()
            self._lock.notify()
            return fut

    def _run(self) -> None:
        while True:
            with self._lock:
                self._lock.wait_for(lambda: self._closed or self._queue)
                if self._closed:
                    return
                fn, (args, kwargs, fut) = self._queue.popitem(last=False)
            try:
                fut.set_result(fn(*args, **kwargs))
            except Exception as exc:
                fut.set_exception(exc)

    def shutdown(self, wait: bool = False, cancel_futures: bool = True) -> None:
        with self._lock:
            self._closed = True
            for _args, _kw, fut in self._queue.values():
                fut.set_result(None)  # dropped (not "cancelled": viser would print that for each)
            self._queue.clear()
            self._lock.notify_all()


class _Turn:
    """A waiting caller: set when a slot is handed over, with the lane it got."""

    __slots__ = ("event", "lane")

    def __init__(self) -> None:
        self.event, self.lane = threading.Event(), ""


class FairSlots:
    """At most ``n`` holders at once, handed out in the order they were asked for (a context manager),
    plus ``fast`` slots that only cheap turns may use.

    A cheap turn (a change whose results are cached: only drawing is left, a fraction of a second) may use a
    free ordinary slot or a fast one, and a freed ordinary slot goes to a waiting cheap turn first: a word
    length change does not wait behind other tabs' data changes. Cheap turns are short, so ordinary ones
    wait for them at most a few of those fractions.

    :meth:`turn` is the same with a report: a caller that has to wait is told, and told again whenever its
    place changes, how many tabs are ahead of it (those holding a slot it may use and those waiting before it).
    """

    #: Seconds between two looks at a waiting caller's place in the queue.
    REPORT_EVERY = 0.25

    def __init__(self, n: int, fast: int = 0):
        self.n, self.fast = max(1, int(n)), max(0, int(fast))
        self._free, self._fast_free = self.n, self.fast
        self._lock = threading.Lock()
        self._waiting: deque[_Turn] = deque()  # ordinary turns
        self._cheap: deque[_Turn] = deque()  # cheap turns

    def acquire(self, on_wait: Callable[[int], None] | None = None, cheap: bool = False) -> str:
        """Wait for a slot; returns its lane (``"slot"`` or ``"fast"``), which :meth:`release` takes back."""
        with self._lock:
            if cheap and not self._cheap:
                if self._free > 0 and not self._waiting:
                    self._free -= 1
                    return "slot"
                if self._fast_free > 0:
                    self._fast_free -= 1
                    return "fast"
            elif not cheap and self._free > 0 and not self._waiting and not self._cheap:
                self._free -= 1
                return "slot"
            turn = _Turn()
            (self._cheap if cheap else self._waiting).append(turn)
            ahead = self._ahead(turn, cheap)
        if on_wait is None:
            turn.event.wait()  # release() hands its slot over directly: nobody can barge in between
            return turn.lane
        on_wait(ahead)
        while not turn.event.wait(self.REPORT_EVERY):
            with self._lock:
                now = self._ahead(turn, cheap)
            if now != ahead and not turn.event.is_set():
                ahead = now
                on_wait(ahead)
        return turn.lane

    def _ahead(self, turn: _Turn, cheap: bool) -> int:
        """Callers ahead of waiting ``turn``: holders of the slots it may use plus those served before it
        (lock held)."""
        queue = self._cheap if cheap else self._waiting
        try:
            before = next(i for i, t in enumerate(queue) if t is turn)
        except StopIteration:  # handed a slot meanwhile
            return 0
        if cheap:
            return (self.n - self._free) + (self.fast - self._fast_free) + before
        return (self.n - self._free) + len(self._cheap) + before

    def release(self, lane: str = "slot") -> None:
        with self._lock:
            if self._cheap:  # a cheap turn takes whichever slot is freed
                turn = self._cheap.popleft()
            elif lane == "slot" and self._waiting:
                turn = self._waiting.popleft()
            else:
                if lane == "fast":
                    self._fast_free += 1
                else:
                    self._free += 1
                return
            turn.lane = lane
            turn.event.set()

    @contextlib.contextmanager
    def turn(self, on_wait: Callable[[int], None] | None = None, cheap: bool = False):
        """``with slots.turn(report):`` holds a slot for the block; ``report(n)`` while ``n`` callers are ahead."""
        lane = self.acquire(on_wait, cheap)
        try:
            yield self
        finally:
            self.release(lane)

    def __enter__(self) -> FairSlots:
        self.acquire()
        return self

    def __exit__(self, *exc) -> None:
        self.release()
