"""One computation of a tab drawn frame by frame, for a linear plant (:meth:`app.dashboard.session.Session._compute`)
and a nonlinear one (:func:`app.dashboard.koopman_session.compute_nonlinear`) alike: the progress and queue
reports, one turn of the compute slots per frame, staleness checks, the "ready" line and the errors shown.

Everything here runs in the tab's worker thread (see the list in :mod:`app.dashboard.session`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from qsid_core import QsidError

from .pool import PoolFailure, Superseded

__all__ = ["reporters", "draw_frames"]


def reporters(session: Any, gen: int) -> tuple[Callable[[int, int, str], None], Callable[[int], None]]:
    """``(on_progress, on_queued)`` of computation ``gen``: the progress bar, and the status line while it
    waits for a compute slot (:func:`draw_frames` says "computing …" again once its turn comes)."""
    c = session.controls
    c.status.content = "computing …"

    def progress(done: int, total: int, text: str) -> None:
        if not session._stale(gen):
            session.ui.show_progress(done / total, text)

    def queued(ahead: int) -> None:
        session._waited = True
        if not session._stale(gen):
            c.status.content = f"queued behind {ahead} tab{'s' if ahead != 1 else ''} (the server is busy) …"

    session._waited = False
    return progress, queued


def draw_frames(
    session: Any,
    gen: int,
    frames: Any,
    t0: float,
    queued: Callable[[int], None],
    cheap: bool = False,
    unusable: Callable[[Any], str | None] | None = None,
) -> int:
    """Draw ``frames`` (a generator of a linear or a nonlinear plant's frames) one turn of the compute slots
    at a time until the complete one, a newer generation, or an error shown in the panel; returns ``gen``.

    ``queued``: told how many tabs are ahead while it waits for a slot (:func:`reporters`); ``cheap``: only
    drawing is left (a cheap turn); ``unusable(frame)``: why a frame cannot be drawn (shown instead)."""
    c = session.controls
    try:
        while True:
            with session.app.slots.turn(queued, cheap):  # (4) at most a few tabs compute at once, in turn
                if session._stale(gen):
                    return gen
                if session._waited:  # its turn came
                    c.status.content, session._waited = "computing …", False
                frame = next(frames, None)
            if frame is None or session._stale(gen):
                return gen
            why = unusable(frame) if unusable is not None else None
            if why:  # all identifications failed, eps not finite: never 'ready'
                session._show_error(why)
                return gen
            if not session._draw(frame, gen):
                return gen
            session.timings["current" if frame.stage == "current" else "all"] = time.perf_counter() - t0
            if frame.complete:
                c.progress.value = 100.0
                c.status.content = (
                    f"ready · b = {frame.bits} drawn in {session.timings['current']:.2f} s, "
                    f"all curves in {session.timings['all']:.2f} s"
                )
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
