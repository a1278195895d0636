"""Every view of every lesson (and of the panel's defaults) draws consistent data: the dashboard's own path
(lesson -> Values -> frames -> the registry's views, as a tab draws them) checked by :func:`drawn.check_drawn`
at the first frame (the current b only) and the last (every b).

The lessons run at a small data size (their other settings as they are): the checker asks what must hold at
any size (x and y equally long, every band enclosing its line); ``tests/figures/test_drawn_truth.py`` checks
the values against the engine's result."""

from __future__ import annotations

import pytest
from drawn import check_drawn

from app.dashboard.session import iter_frames
from app.figures import registry
from app.frames.cache import SharedCache
from app.frames.render import build_figures
from app.lessons.table import LESSONS, lesson_values
from app.settings.values import Values, is_nonlinear

LINEAR_SMALL = dict(trajectories=10, steps=60, realizations=10)
NONLINEAR_SMALL = dict(trajectories=20, steps=50, realizations=3, mpc_steps=30)


def check_every_view(v: Values, what: str) -> set[str]:
    """Check the first and the last frame's figures of ``v``; the views drawn."""
    if is_nonlinear(v.system):
        frames = list(iter_frames(v.replace(**NONLINEAR_SMALL)))
        build, views = build_figures, registry.KOOPMAN_VIEWS
    else:
        frames = list(iter_frames(v.replace(**LINEAR_SMALL), SharedCache()))
        build, views = build_figures, registry.VIEWS
    assert frames[-1].complete
    drawn: set[str] = set()
    for frame in (frames[0], frames[-1]):
        figs = build(frame)
        assert list(figs) == [view.name for view in views]
        for name, fig in figs.items():
            check_drawn(fig, f"{what} ({frame.stage}) {name}")
            drawn.add(name)
    return drawn


@pytest.mark.slow  # 13 lessons, each computed (at a small size) for every b
@pytest.mark.parametrize("lesson", [les.name for les in LESSONS])
def test_every_view_of_every_lesson_draws_consistent_data(lesson):
    v = lesson_values(lesson)
    assert check_every_view(v, f"lesson {lesson}")


def test_every_view_of_the_default_panel_draws_consistent_data():
    assert check_every_view(Values(), "defaults") == {v.name for v in registry.VIEWS}
