"""What ``qsid-dashboard`` prints while it starts: each step as it begins, and a line every few seconds while
one takes long, so that a start that compiles the kernels (minutes on a busy machine) never looks hung.

The engine reports its warm-up steps through a callback (:func:`qsid_core.studies.compile_kernels`); this
module words them and prints them. Lines go to stdout, flushed, each starting ``qsid dashboard:`` like the ready
line that follows them.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import TextIO

__all__ = ["StartupReport", "TICK_SECONDS"]

#: Seconds between two "still ..." lines while one step runs.
TICK_SECONDS = 5.0


class StartupReport:
    """Prints the start-up's steps and, while a step runs, a "still ..." line every ``tick`` seconds.

    Use as a context manager around the start-up (the ticker thread ends with it). :meth:`step` begins a step
    (``what``, and optionally ``k`` of ``n``); the ticker repeats it with the seconds the step and the whole
    start have taken so far.
    """

    def __init__(self, out: TextIO | None = None, tick: float = TICK_SECONDS):
        self.out = out if out is not None else sys.stdout
        self.tick = tick
        self._lock = threading.Lock()
        self._what = ""
        self._start = self._step_start = self._last = time.monotonic()
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._run, name="qsid-startup-report", daemon=True)

    def __enter__(self) -> StartupReport:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._done.set()
        self._thread.join(timeout=2 * self.tick)

    def say(self, text: str) -> None:
        """One line now (``qsid dashboard: text``), not repeated."""
        with self._lock:
            self._what = ""
            self._print(text)

    def _print(self, text: str) -> None:
        self._last = time.monotonic()
        print(f"qsid dashboard: {text}", file=self.out, flush=True)

    def step(self, what: str, k: int | None = None, n: int | None = None) -> None:
        """Step ``what`` begins (``k`` of ``n``, e.g. kernel 3 of 7), printed now and repeated while it runs."""
        with self._lock:
            self._what = f"{what} ({k} of {n})" if k is not None and n is not None else what
            self._step_start = time.monotonic()
            self._print(self._what)

    def _run(self) -> None:
        while not self._done.wait(self.tick / 5):
            with self._lock:
                now = time.monotonic()
                if self._what and now - self._last >= self.tick:
                    short = self._what.split(":")[0]  # "kernel 3 of 7: the box QP" -> "kernel 3 of 7"
                    self._print(
                        f"still {short}: {now - self._step_start:.0f} s so far, {now - self._start:.0f} s in all"
                    )

    @property
    def elapsed(self) -> float:
        """Seconds since the report began."""
        return time.monotonic() - self._start
