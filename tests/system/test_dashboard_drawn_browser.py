"""The data plotly draws in a real headless Chromium (1366×768) is the data the server pushed, and it is
consistent: every view of every lesson, checked by :func:`drawn.check_drawn`.

One server (shared with test_dashboard_legibility.py, which draws the lessons from the results computed
here), one browser, one tab. For each lesson of :data:`app.lessons.table.LESSONS` the tab opens the
lesson (as its selector does) and the tab's worker is held right after it drew the lesson's first frame
(:class:`FirstFrame`), so the page and the server stand still on one result; then every group the lesson's
system offers in the plots panel's "show" dropdown is brought forward (as a lesson brings its own) and, for
every plot shown, what plotly.js holds in the page (``el.data``) must

* be the figure the server pushed to that plot (the same traces, the same numbers, none lost or changed on
  the way: x, y, z, hover texts, error bars),
* pass :func:`drawn.check_drawn` (x and y equally long, error bars as long as y, every band enclosing its
  line),
* and, for the norm-against-time plot of a linear plant, draw as its min..max band and median exactly the
  min, max and median of ``‖x_t‖`` of the closed loops of the frame drawn (the engine's loops, floored as
  the engine floors converged norms).

Then the worker goes on, and the lesson's last frame (every b) is checked the same way once drawn.
"""

from __future__ import annotations

import json
import threading
import time
from typing import Any

import numpy as np
import pytest
from drawn import band_edges, check_drawn, line, values
from test_dashboard_browser import ARGS, CHROMIUM, TIMEOUT_MS, _require_browser
from test_dashboard_legibility import _open
from test_dashboard_teach_browser import ACTIVE_TAB

pytestmark = [pytest.mark.browser, pytest.mark.slow]

#: Every visible plot's traces as plotly.js holds them (typed arrays copied out, nested ones too).
VISIBLE_DATA = """() => {
  const KEYS = ['x', 'y', 'z', 'text', 'fill', 'mode', 'name', 'legendgroup', 'xaxis', 'yaxis', 'type',
                'error_y', 'error_x'];
  const plain = v => ArrayBuffer.isView(v) ? Array.from(v)
    : Array.isArray(v) ? v.map(plain)
    : (v && typeof v === 'object') ? Object.fromEntries(Object.entries(v).map(([k, w]) => [k, plain(w)]))
    : v;
  return [...document.querySelectorAll('.js-plotly-plot')]
    .filter(e => e.offsetParent !== null && Array.isArray(e.data))
    .map(e => e.data.map(t => Object.fromEntries(KEYS.filter(k => k in t).map(k => [k, plain(t[k])]))));
}"""
#: The trace keys compared between page and server: as strings, and as numbers.
LABELS = ("type", "name", "fill", "mode", "legendgroup", "xaxis", "yaxis")
ARRAYS = ("x", "y", "z")
#: The norm plot's median line of estimator ``label``.
MEDIAN = "{} ‖x_t‖ (median; band: min..max)"


class FirstFrame:
    """Holds a tab's worker right after it drew the first frame of the lesson it is armed for, until released:
    the page and the server then stand still on that frame (a newer change is not computed meanwhile)."""

    def __init__(self, session: Any):
        self.session, self._draw = session, session._draw
        self.lesson: str | None = None
        self.frame: Any = None
        self.drawn, self.go = threading.Event(), threading.Event()
        session._draw = self.draw  # (the worker calls it once per frame, outside the compute slots)

    def arm(self, lesson: str) -> None:
        self.frame, self.lesson = None, lesson
        self.drawn.clear()
        self.go.clear()

    def draw(self, frame: Any, gen: int) -> bool:
        ok = self._draw(frame, gen)
        if ok and self.lesson is not None and frame.values.lesson == self.lesson:
            self.lesson, self.frame = None, frame
            self.drawn.set()
            self.go.wait(TIMEOUT_MS / 1000)
        return ok

    def wait(self) -> Any:
        assert self.drawn.wait(TIMEOUT_MS / 1000), "the lesson's first frame was not drawn (hung?)"
        return self.frame

    def release(self) -> None:
        self.go.set()


def _plain(v: Any) -> list | None:
    """An array of a trace as a list of str (labels) or None (no array)."""
    if v is None:
        return None
    if isinstance(v, dict) and "bdata" in v:
        return None
    return v if any(isinstance(x, str) for x in v) else None


def _same_array(mine: Any, theirs: Any, what: str) -> None:
    a, b = _plain(mine), _plain(theirs)
    if a is not None or b is not None:  # categories or labels
        assert a == b, f"{what}: the page has {str(a)[:200]} where the server sent {str(b)[:200]}"
        return
    x, y = values(mine), values(theirs)
    assert x.shape == y.shape, f"{what}: {x.size} values in the page, {y.size} sent by the server"
    same = (x == y) | (np.isnan(x) & np.isnan(y))
    assert same.all(), (
        f"{what}: the page differs from the server at {int((~same).sum())} of {x.size} points, first at index "
        f"{int(np.argmin(same))}: {x[~same][0]!r} drawn, {y[~same][0]!r} sent"
    )


def same_traces(page: list[dict], server: list[dict], where: str) -> None:
    """Assert the traces plotly.js holds in the page are those the server pushed (numbers exactly equal)."""
    assert [t.get("name") for t in page] == [t.get("name") for t in server], (
        f"{where}: the page draws traces {[t.get('name') for t in page]}, the server sent "
        f"{[t.get('name') for t in server]}"
    )
    for i, (mine, theirs) in enumerate(zip(page, server)):
        what = f"{where}: trace {i} ({theirs.get('name')!r})"
        for key in LABELS:
            assert mine.get(key) == theirs.get(key), f"{what}: {key} {mine.get(key)!r} ≠ {theirs.get(key)!r} sent"
        for key in ARRAYS:
            if key in mine or key in theirs:
                _same_array(mine.get(key), theirs.get(key), f"{what} {key}")
        if isinstance(theirs.get("text"), list):
            assert mine.get("text") == theirs["text"], f"{what}: hover texts differ from the server's"
        for key in ("error_y", "error_x"):
            for arr in ("array", "arrayminus"):
                sent = (theirs.get(key) or {}).get(arr)
                if sent is not None:
                    _same_array((mine.get(key) or {}).get(arr), sent, f"{what} {key}.{arr}")


class Pushed:
    """The figures the server pushed to the tab's plot handles, as JSON data lists (parsed once per figure)."""

    def __init__(self, session: Any):
        self.session = session
        self._parsed: dict[str, tuple[Any, list]] = {}

    def data(self, view: str) -> list[dict]:
        fig = self.session.plots[view].figure
        known = self._parsed.get(view)
        if known is None or known[0] is not fig:
            known = (fig, json.loads(fig.to_json())["data"])
            self._parsed[view] = known
        return known[1]

    def shown(self, group: str) -> list[str]:
        """The views of ``group`` in the order the panel shows them (a lesson's key view first)."""
        from app.figures.registry import ALL_VIEWS

        names = [v.name for v in ALL_VIEWS if v.tab == group]
        return sorted(names, key=lambda n: float(self.session.plots[n].order))


def _page_matches(page, pushed: Pushed, group: str, where: str) -> list[tuple[str, list[dict]]]:
    """Wait until the plots the page shows are the server's figures of ``group`` (plotly draws what arrives
    a moment later); (view, the page's traces) for each; fails with the last difference after the guard."""
    views = pushed.shown(group)
    end = time.monotonic() + TIMEOUT_MS / 1000
    while True:
        shown = page.evaluate(VISIBLE_DATA)
        try:
            assert len(shown) == len(views), f"{where}: {len(shown)} plots shown, the group has {views}"
            for view, data in zip(views, shown):
                same_traces(data, pushed.data(view), f"{where} {view}")
            return list(zip(views, shown))
        except AssertionError:
            if time.monotonic() > end:
                raise
            page.wait_for_timeout(200)


def _norms(frame: Any, label: str) -> np.ndarray:
    """‖x_t‖ of the frame's closed loops of ``label`` that ran, floored as the engine floors converged norms."""
    from qsid_core.control import CONVERGED_REL_FLOOR

    lp = frame.loops[label]
    ok = ~np.asarray([bool(f) for f in lp.failure])
    return np.maximum(np.linalg.norm(lp.states[ok], axis=-1), CONVERGED_REL_FLOOR * np.linalg.norm(frame.x0))


def check_norm_band(data: list[dict], frame: Any, where: str) -> int:
    """The norm plot's bands and medians are the min, max and median of the frame's loops' ‖x_t‖; the bands
    checked."""
    bands = 0
    for label in frame.labels:
        norms = _norms(frame, label)
        if norms.size == 0:
            continue
        t, med = line(data, MEDIAN.format(label))
        np.testing.assert_allclose(med, np.median(norms, axis=0), rtol=1e-9, err_msg=f"{where}: {label} median")
        band = [tr for tr in data if tr.get("fill") and tr.get("legendgroup") == label]
        assert len(band) == 1, f"{where}: {len(band)} bands for {label}"
        assert len(values(band[0]["x"])) == len(values(band[0]["y"])) == 2 * norms.shape[1], (
            f"{where}: {label}'s band has {len(values(band[0]['x']))} x and {len(values(band[0]['y']))} y values "
            f"for {norms.shape[1]} steps"
        )
        bx, hi, lo = band_edges(band[0])
        np.testing.assert_array_equal(bx, t, err_msg=f"{where}: {label} band t")
        np.testing.assert_allclose(hi, norms.max(axis=0), rtol=1e-9, err_msg=f"{where}: {label} band max")
        np.testing.assert_allclose(lo, norms.min(axis=0), rtol=1e-9, err_msg=f"{where}: {label} band min")
        bands += 1
    return bands


def check_frame(page, session, pushed: Pushed, frame: Any, lesson: str, counts: dict) -> None:
    """Every group the tab's system offers brought forward, every plot shown checked (module docstring)."""
    from app.figures.registry import KOOPMAN_TABS, TABS
    from app.settings.values import is_nonlinear

    groups = tuple(session.views.group.options)
    assert groups == (KOOPMAN_TABS if is_nonlinear(frame.values.system) else TABS), f"{lesson}: groups {groups}"
    for group in groups:
        session.views.show(group)  # as a lesson brings its group forward (the dropdown shows it too)
        page.wait_for_function(f"({ACTIVE_TAB})() === {group!r}", timeout=TIMEOUT_MS)
        where = f"lesson {lesson} ({frame.stage}, b = {frame.bits}), {group}:"
        for view, data in _page_matches(page, pushed, group, where):
            check_drawn(data, f"{where} {view}")
            counts["views"] += 1
            counts["traces"] += len(data)
            counts["bands"] += sum(tr.get("fill") == "toself" for tr in data)
            if view == "norm_time":
                assert check_norm_band(data, frame, f"{where} {view}") > 0, f"{where}: no band of ‖x_t‖ drawn"
                counts["norm bands"] += 1


def test_every_view_of_every_lesson_draws_the_servers_data_in_the_browser(lessons_app):
    _require_browser()
    from playwright.sync_api import sync_playwright

    from app.lessons.table import LESSONS, NONE

    counts = dict(lessons=0, frames=0, views=0, traces=0, bands=0, **{"norm bands": 0})
    app = lessons_app
    # every lesson computed here, none taken whole from the cache: the frames drawn while computing are checked
    app.cache.clear()
    held: FirstFrame | None = None
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
        try:
            page, session = _open(browser.new_context(viewport={"width": 1366, "height": 768}), app)
            session.controls["lesson"].value = NONE  # (a new tab opens on the first lesson: each is a change)
            assert session.wait_idle(TIMEOUT_MS / 1000)
            held, pushed = FirstFrame(session), Pushed(session)
            for les in LESSONS:
                t0 = time.monotonic()
                held.arm(les.name)
                session.controls["lesson"].value = les.name
                first = held.wait()
                try:
                    check_frame(page, session, pushed, first, les.name, counts)
                finally:
                    held.release()
                assert session.wait_idle(TIMEOUT_MS / 1000)
                last = session.last_frame
                assert last is not None and last.complete and last.values.lesson == les.name
                assert session.last_error is None, f"{les.name}: {session.last_error}"
                if last is not first:
                    check_frame(page, session, pushed, last, les.name, counts)
                    counts["frames"] += 1
                counts["frames"] += 1
                counts["lessons"] += 1
                print(f"{les.name}: {time.monotonic() - t0:.1f} s", flush=True)
        finally:
            if held is not None:
                held.release()
            browser.close()
    print(counts)
    assert counts["lessons"] == len(LESSONS)
    assert counts["norm bands"] > 0
