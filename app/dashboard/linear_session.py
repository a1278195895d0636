"""A tab's worker for a linear plant: one computation drawn frame by frame (:func:`compute_linear`).

:class:`app.dashboard.session.Session` calls it (in the tab's worker, see the list of threads there) with the
settings to compute; the frames come from :func:`~app.dashboard.stages.iter_frames`, each drawn unless a newer
change arrived meanwhile. :func:`app.dashboard.koopman_session.compute_nonlinear` does the same for a nonlinear plant.
"""

from __future__ import annotations

import time
from typing import Any

from qsid_core import QsidError

from .inputs import unusable
from .pool import PoolFailure, Superseded
from .settings import Values
from .stages import iter_frames

__all__ = ["compute_linear"]


def compute_linear(session: Any, gen: int, values: Values) -> int:
    """Compute and draw generation ``gen`` for a linear plant; returns the generation handled."""
    c = session.controls
    t0 = time.perf_counter()

    def progress(done: int, total: int, text: str) -> None:
        if not session._stale(gen):
            session.ui.show_progress(done / total, text)

    waited: list = []

    def queued(ahead: int) -> None:
        waited.append(ahead)
        if not session._stale(gen):
            c.status.content = f"queued behind {ahead} tab{'s' if ahead != 1 else ''} (the server is busy) …"

    c.status.content = "computing …"
    last = session.last_frame  # only drawing left if just display settings changed since a complete frame
    cheap = last is not None and last.complete and values.same_results(last.values)
    frames = iter_frames(
        values,
        session.app.cache,
        session.app.pool.guarded(lambda: session._stale(gen)),
        session.app.tasks,
        should_stop=lambda: session._stale(gen),
        on_progress=progress,
        memo=session.rows_memo,
    )
    try:
        while True:
            with session.app.slots.turn(queued, cheap):  # (4) at most a few tabs compute at once, in turn
                if session._stale(gen):
                    return gen
                if waited:  # its turn came
                    c.status.content, waited[:] = "computing …", []
                frame = next(frames, None)
            if frame is None or session._stale(gen):
                return gen
            why = unusable(frame)
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
