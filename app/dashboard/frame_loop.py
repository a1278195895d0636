"""One computation of a tab drawn frame by frame (:meth:`app.dashboard.session.Session._compute`), for a linear
and a nonlinear plant alike: the progress and queue
reports, one turn of the compute slots per frame, staleness checks, the "ready" line and the errors shown.

Everything here runs in the tab's worker thread (see the list in :mod:`app.dashboard.session`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from qsid_core import QsidError

from .pool import PoolFailure, Superseded

__all__ = ["Reporters", "draw_frames", "ready_line"]


class Reporters:
    """What computation ``gen`` of ``session`` shows while it runs: :meth:`progress` (the progress bar) and
    :meth:`queued` (the status line while it waits for a compute slot; ``waited`` until :func:`draw_frames`
    says "computing …" again once its turn comes)."""

    def __init__(self, session: Any, gen: int):
        self.session, self.gen, self.waited = session, gen, False
        session.controls.status.content = "computing …"

    def progress(self, done: int, total: int, text: str) -> None:
        if not self.session._stale(self.gen):
            self.session.ui.show_progress(done / total, text)

    def queued(self, ahead: int) -> None:
        self.waited = True
        if not self.session._stale(self.gen):
            self.session.controls.status.content = (
                f"queued behind {ahead} tab{'s' if ahead != 1 else ''} (the server is busy) …"
            )


def ready_line(bits: int, timings: dict[str, float], budget_done: bool, budget_wanted: bool) -> str:
    """The status line of a tab whose curves are all drawn: when b and all curves were drawn (seconds since the
    change) and, with a bit budget set, the budget study: still computing, or how long it took after the curves.

    ``timings``: ``"current"``, ``"all"`` and (once drawn) ``"budget"``, seconds from the change to each frame.
    """
    line = f"ready · b = {bits} drawn in {timings['current']:.2f} s, all curves in {timings['all']:.2f} s"
    if budget_done:
        return f"{line} · bit budget study: {timings['budget'] - timings['all']:.1f} s"
    return f"{line} · computing the bit budget study …" if budget_wanted else line


def draw_frames(
    session: Any,
    gen: int,
    frames: Any,
    t0: float,
    reports: Reporters,
    cheap: bool = False,
    unusable: Callable[[Any], str | None] | None = None,
) -> int:
    """Draw ``frames`` (a generator of a linear or a nonlinear plant's frames) one turn of the compute slots
    at a time until the complete one, a newer generation, or an error shown in the panel; returns ``gen``.

    ``reports``: the computation's :class:`Reporters` (told how many tabs are ahead while it waits for a slot); ``cheap``: only
    drawing is left (a cheap turn); ``unusable(frame)``: why a frame cannot be drawn (shown instead)."""
    c = session.controls
    try:
        while True:
            with session.app.slots.turn(reports.queued, cheap):  # (4) at most a few tabs compute at once, in turn
                if session._stale(gen):
                    return gen
                if reports.waited:  # its turn came
                    c.status.content, reports.waited = "computing …", False
                frame = next(frames, None)
            if frame is None or session._stale(gen):
                return gen
            why = unusable(frame) if unusable is not None else None
            if why:  # all identifications failed, eps not finite: never 'ready'
                session._show_error(why)
                return gen
            if not session._draw(frame, gen):
                return gen
            budget = getattr(frame, "budget", None)
            stage = "current" if frame.stage == "current" else "budget" if budget is not None else "all"
            session.timings[stage] = time.perf_counter() - t0
            if frame.complete:
                c.progress.value = 100.0
                wanted = bool(float(getattr(frame.values, "total_bits", 0.0)))
                c.status.content = ready_line(frame.bits, session.timings, budget is not None, wanted)
                if budget is not None or not wanted:
                    return gen  # the last frame: no further turn to wait for
    except (PoolFailure, Superseded) as exc:
        if isinstance(exc, PoolFailure):
            raise
    except QsidError as exc:
        session._show_error(str(exc))
    except (RecursionError, OverflowError, MemoryError, ZeroDivisionError, FloatingPointError) as exc:
        session._show_error(
            f"these settings cannot be computed ({type(exc).__name__}: {exc}); try smaller or less extreme values"
        )
    finally:
        frames.close()
    return gen
