"""Memory given back once the last tab has been gone for a while.

While tabs are open the server keeps their results (:class:`~app.dashboard.cache.SharedCache`) and
the pool workers keep the data of the last tasks; glibc keeps freed pages. When no tab is left for
:data:`IDLE_SECONDS`, :class:`IdleRelease` calls the server's release (clear the cache, fresh pool
workers for the old ones, trim) once. A tab that opens meanwhile cancels it; a reload (close, then open within seconds)
therefore keeps every result.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

__all__ = ["IdleRelease", "IDLE_SECONDS"]

#: Seconds without any tab before the server gives its memory back.
IDLE_SECONDS = 20.0


class IdleRelease:
    """Runs ``release()`` once, ``delay`` seconds after :meth:`schedule`, unless :meth:`cancel` came first.

    The timer runs in a daemon thread (``qsid-idle-release``), at most one at a time.
    """

    def __init__(self, release: Callable[[], None], delay: float = IDLE_SECONDS):
        self._release = release
        self.delay = float(delay)
        self._lock = threading.Lock()  # guards _timer: tabs open and close from viser's callback threads
        self._timer: threading.Timer | None = None
        self.releases = 0

    def schedule(self) -> None:
        """The last tab closed: release in ``delay`` seconds (a pending release starts over)."""
        with self._lock:
            if self._timer is not None:
                self._timer.cancel()
            self._timer = threading.Timer(self.delay, self._fire)
            self._timer.name = "qsid-idle-release"
            self._timer.daemon = True
            self._timer.start()

    def cancel(self) -> None:
        """A tab opened (or the server stops): no release."""
        with self._lock:
            if self._timer is not None:
                self._timer.cancel()
                self._timer = None

    @property
    def pending(self) -> bool:
        with self._lock:
            return self._timer is not None

    def _fire(self) -> None:
        with self._lock:
            if self._timer is None or threading.current_thread() is not self._timer:
                return  # cancelled or rescheduled meanwhile
            self._timer = None
        self.releases += 1
        self._release()
