"""Tabs drawing the same state share one render (:class:`app.frames.render.Figures`): each figure is built, styled
and made JSON once, and every tab pushes that very figure; other settings, layouts and a pinned result do not
share, and what every tab pushes is what a tab rendering on its own would push."""

from __future__ import annotations

import dataclasses

from support import SMALL, Tab

from app.dashboard.controls import panel_form
from app.dashboard.server import DashboardApp
from app.figures.raw import to_json
from app.figures.traces import MarkedAt, move_current_bits
from app.frames.cache import SharedCache
from app.frames.compute import iter_frames
from app.frames.render import Figures, Renderer, build_figures
from app.settings.values import Values, resolve_system

V = Values(mpc_steps=15, **SMALL)


def pushes(renderer: Renderer, frames: list, narrow: bool = False, pinned=None) -> list[dict]:
    """What ``renderer`` pushes for each of ``frames``: view name -> (the figure object, its JSON)."""
    out = []
    for frame in frames:
        frame.pinned = pinned
        r = renderer.render(frame, narrow=narrow)
        out.append({name: (fig, fig.to_json()) for name, fig in r.figures.items()})
    return out


def json_of(seq: list[dict]) -> list[dict]:
    return [{name: js for name, (_fig, js) in d.items()} for d in seq]


def test_two_tabs_on_the_same_settings_share_every_figure():
    cache, shared = SharedCache(), Figures()
    first, second = Renderer(shared), Renderer(shared)
    a = pushes(first, list(iter_frames(V, cache)))
    built = shared.builds
    # every view built once (frames redraw some again), and the 3-D scene and the summary at the current b
    assert built == len({name for d in a for name in d}) + 2
    b = pushes(second, list(iter_frames(V, cache)))
    assert shared.builds == built and shared.reused >= len(b[0])  # the second tab built nothing ...
    pushed = {name: fig for d in b for name, (fig, _js) in d.items()}
    assert pushed and all(pushed[name] is first.figures[name] for name in pushed)  # ... it pushes the first's
    # a b change in both: the current views and the moved markers are made once, by the first tab that needs them
    pushes(first, list(iter_frames(V.replace(bits=7), cache)))
    after = shared.builds
    assert after > built
    moved = pushes(second, list(iter_frames(V.replace(bits=7), cache)))
    assert shared.builds == after
    assert moved[0]["error"][0] is first.figures["error"] and isinstance(moved[0]["error"][0].wire, MarkedAt)


def test_what_a_sharing_tab_pushes_is_what_a_tab_on_its_own_pushes():
    """Other settings, the presenter's and a phone's layouts and a pinned result: each pushes what a tab rendering
    on its own pushes, frame by frame, however many tabs drew before it."""
    cache, shared = SharedCache(), Figures()
    pinned = dataclasses.replace(list(iter_frames(V.replace(bits=3), cache))[-1], pinned=None)
    cases = [
        (V, False, None),
        (V.replace(log_q=(1.0, -1.0, -1.0)), False, None),  # the same models, other MPC weights: other curves
        (V.replace(presenter=True), False, None),
        (V, True, None),  # a phone
        (V, False, pinned),
    ]
    for round_ in (1, 2):
        before = shared.builds
        for values, narrow, pin in cases:
            for step in (values, values.replace(bits=9)):
                frames = list(iter_frames(step, cache))
                alone = pushes(Renderer(), frames, narrow, pin)
                together = pushes(Renderer(shared), frames, narrow, pin)
                assert json_of(together) == json_of(alone), (values, narrow, pin is not None, step.bits)
        assert (shared.builds == before) == (round_ == 2)  # the second round finds every figure made
    # one tab walking through b's: the only figures new to the server are its curves with the marker moved
    kept = set(shared.store)
    for values, narrow, pin in cases:
        r = Renderer(shared)
        for step in (values, values.replace(bits=9), values):
            pushes(r, list(iter_frames(step, cache)), narrow, pin)
    new = set(shared.store) - kept
    assert new and all(len(k) == 2 and k[1] == 9 and k[0] in kept for k in new)
    # the views drawn over a pinned result are the pinning tab's own: never kept for other tabs
    own = pushes(Renderer(shared), list(iter_frames(V, cache)), pinned=pinned)[-1]
    kept_ids = {id(shared.store[k]) for k in shared.store}
    assert {name for name, (fig, _js) in own.items() if id(fig) not in kept_ids} == {"error", "cost", "bound"}


def test_a_moved_marker_is_the_figure_moved_in_place():
    cache = SharedCache()
    frame = list(iter_frames(V, cache))[-1]
    built, twin = build_figures(frame), build_figures(frame)
    for name in ("error", "cost", "bits", "bound", "residual"):
        fig = built[name]
        before = to_json(fig)
        text = MarkedAt(fig, 11).to_json()
        assert to_json(fig) == before  # the figure as built is left as it is
        moved = twin[name]
        assert text == to_json(move_current_bits(moved, 11)) and text != before
        assert [s.x0 for s in MarkedAt(fig, 11).layout.shapes] == [s.x0 for s in moved.layout.shapes]


def test_a_new_tab_finds_its_first_view_computed_and_drawn_by_the_start():
    """The server's first view is computed for the settings a new tab's panel reads (texts, x0 and weights filled
    in): the tab computes nothing and builds no figure, it only pushes."""
    app = DashboardApp(host="127.0.0.1", port=0, workers=0, settings=V)
    try:
        assert app.prefill() is None
        kinds, builds = app.cache.kinds(), app.figures.builds
        tab = Tab(app).wait()
        assert tab.frame.values == panel_form(V, resolve_system(V).system) != V
        assert tab.frame.complete and app.cache.kinds() == kinds and app.figures.builds == builds
        tab.set(bits=6)  # a b change: its figures made once, for the next tab changing to it too
        made = app.figures.builds
        assert made > builds
        other = Tab(app).wait()
        other.set(bits=6)
        assert app.figures.builds == made
        assert other.session.plots["eigen"].figure is tab.session.plots["eigen"].figure
        tab.close()
        other.close()
    finally:
        app.stop()
