"""Every plot legible at the sizes a class uses: laptop, projector (presenter mode) and phone, in headless Chromium.

For each mode of :data:`MODES` (1366×768 and 1920×1080, normal and presenter; 390×844 phone) the test opens a
tab at that size (the server tells a phone from its canvas's shape when the tab connects, as for a real phone),
opens every tab of the plots panel, every lesson and a nonlinear plant's own view (:data:`NONLINEAR`), and
measures the text boxes of every plotly figure shown (:data:`legibility.TEXT_BOXES`); :func:`legibility.judge`
fails on overlapping text, text under the floor (10 px, 16 px in presenter mode), text cut off at a figure's
edge, or a figure narrower than 340 px. For each lesson it also checks what a teacher needs
(:func:`_teacher_checks`): the key plot above the fold and, in presenter mode, panel text at least
``PANEL_FONT`` and the key plot across most of the window.

Environment:

* ``QSID_SCREENSHOT_DIR=assets``: the screenshots of the README and the docs are written there
  (:data:`SHOTS`), so the pictures show what the test measured;
* ``QSID_LEGIBILITY_REPORT=file.json``: every problem found, per mode and place, written there (the
  baseline counts in docs/teaching.rst were made this way).
"""

from __future__ import annotations

import json
import os

import pytest
from legibility import NORMAL_FLOOR, PRESENTER_FLOOR, TEXT_BOXES, Problem, judge, summary
from support import wait_until
from test_dashboard_browser import ARGS, CHROMIUM, TIMEOUT_MS, _require_browser
from test_dashboard_teach_browser import ACTIVE_TAB, KEY_PLOT_WIDTH, PANEL_TEXT, TOP_PLOT, _dismiss_notices

from app.dashboard.presenter import PANEL_FONT
from app.figures.registry import ALL_VIEWS, KOOPMAN_TABS, TABS
from app.lessons.table import LESSONS, NONE
from app.settings.values import NL_INTERACTIVE

pytestmark = pytest.mark.browser

#: (name, viewport, presenter mode)
MODES = (
    ("laptop", (1366, 768), False),
    ("laptop-presenter", (1366, 768), True),
    ("hd", (1920, 1080), False),
    ("hd-presenter", (1920, 1080), True),
    ("phone", (390, 844), False),
)
#: Screenshots written with QSID_SCREENSHOT_DIR: (mode, place) -> file name ("scene": presenter mode's 3-D view).
SHOTS = {
    ("hd", "tab:Identification"): "dashboard.png",
    ("laptop", "lesson:dither"): "teach-dither-normal.png",
    ("hd-presenter", "lesson:fig1"): "teach-fig1-presenter.png",
    ("hd-presenter", "lesson:bound"): "teach-bound-presenter.png",
    ("hd-presenter", "lesson:saturation"): "teach-saturation-presenter.png",
    ("hd-presenter", "scene"): "teach-scene-presenter.png",
    ("laptop-presenter", "lesson:fig1"): "teach-fig1-laptop-presenter.png",
    ("phone", "tab:Identification"): "phone-identification.png",
    ("phone", "lesson:bits-needed"): "phone-bits-needed.png",
    ("phone", "lesson:fig1"): "phone-fig1.png",
    ("hd", "system:van-der-pol"): "nonlinear-van-der-pol.png",
    ("phone", "system:van-der-pol"): "phone-van-der-pol.png",
    ("laptop", "lesson:koopman"): "teach-koopman-normal.png",
    ("hd-presenter", "lesson:bias-variance"): "teach-bias-variance-presenter.png",
}
#: A nonlinear plant's own view (its lessons are among :data:`LESSONS`): the system, then the panel's values.
NONLINEAR = ("van-der-pol", dict(NL_INTERACTIVE, bits=3, guard=True))
# (the per-tab pictures view-*.png are test_dashboard_browser.py's: it computes the data-length study and pins
# a result first)

#: How long (ms) a tab may take to come forward before the test says it cannot be reached (the page is idle by
#: then: every change was drawn; this is not a speed target).
REACH_MS = 20_000


def _tab_shown(page, session, tab: str, click: bool) -> bool:
    """Bring plots group ``tab`` forward (``click``: as the panel's "show" dropdown does) or wait for a lesson
    to; False if the page does not show it."""
    from playwright.sync_api import Error

    try:
        if click:
            session.views.show(tab)
        page.wait_for_function(f"({ACTIVE_TAB})() === {tab!r}", timeout=REACH_MS)
    except Error:
        return False
    return True


def _settled_boxes(page, reads: int = 15) -> list:
    """The text boxes of the figures shown once plotly has laid them out: two reads 300 ms apart that agree
    (a loaded machine lays out later; a layout that stays wrong is measured as it stays)."""
    page.wait_for_timeout(300)
    last = page.evaluate(TEXT_BOXES)
    for _ in range(reads):
        page.wait_for_timeout(300)
        now = page.evaluate(TEXT_BOXES)
        if now == last:
            break
        last = now
    return last


def _measure(page, session, mode, place, shots, found, reached: bool = True) -> None:
    assert session.wait_idle(TIMEOUT_MS / 1000)
    name, size, presenter = mode
    figures = _settled_boxes(page)
    problems = judge(figures, PRESENTER_FLOOR if presenter else NORMAL_FLOOR)
    if not reached:
        problems.append(Problem("none", place, "its plots tab cannot be brought forward"))
    if not figures:
        problems.append(Problem("none", place, "no plot visible"))
    found[name][place] = problems
    _shot(page, name, place, shots)


#: The first plot shown, scrolled to the top of its panel (on a phone: of the bottom sheet, as a person would).
FIRST_PLOT_UP = """() => {
  const gd = [...document.querySelectorAll('.js-plotly-plot')].find(e => e.offsetParent !== null);
  if (gd) gd.scrollIntoView({block: 'start'});
}"""


def _shot(page, mode: str, place: str, shots) -> None:
    if shots and (mode, place) in SHOTS:
        _dismiss_notices(page)
        if mode == "phone":
            page.evaluate(FIRST_PLOT_UP)
        page.mouse.move(1, 1)  # no hint of whatever the pointer was left over
        page.wait_for_timeout(300)
        page.screenshot(path=os.path.join(shots, SHOTS[mode, place]))


def _scene_shot(page, session, mode: str, shots) -> None:
    """Presenter mode's other view, the 3-D scene (one switch away), pictured; then the plot again."""
    if not shots or (mode, "scene") not in SHOTS:
        return
    session.presenter.toggle()
    assert session.wait_idle(TIMEOUT_MS / 1000)
    page.wait_for_timeout(1500)  # the camera moves to frame the loops
    _shot(page, mode, "scene", shots)
    session.presenter.toggle()
    assert session.wait_idle(TIMEOUT_MS / 1000)


def _teacher_checks(page, mode, lesson: str) -> list:
    """What a teacher opening ``lesson`` needs beyond legible text: its key plot starts above the fold (but on a
    phone, where the sheet scrolls); in
    presenter mode the panel's text is large too and the key plot spans most of the window (one view at a
    time; the 3-D scene is one switch away)."""
    name, size, presenter = mode
    out = []
    top = page.evaluate(TOP_PLOT)
    if name != "phone" and not top < size[1]:  # (a phone's plots follow the slider and the lesson's text)
        out.append(Problem("none", lesson, f"the key plot starts below the fold, at {top:.0f} px"))
    if presenter:
        panel, what = page.evaluate(PANEL_TEXT)
        if panel < PANEL_FONT:
            out.append(Problem("none", lesson, f"panel text {panel:.1f} px < {PANEL_FONT} px: {what!r}"))
        width = page.evaluate(KEY_PLOT_WIDTH)
        if width < 0.6 * size[0]:
            out.append(Problem("none", lesson, f"the key plot is {width:.0f} px wide, under 60 % of the window"))
    return out


def _walk(page, session, mode, shots, found) -> None:
    name, size, presenter = mode
    session.controls["presenter"].value = presenter
    assert session.wait_idle(TIMEOUT_MS / 1000)
    found[name] = {}
    session.controls["lesson"].value = NONE  # each lesson below is then a change (and brings its tab forward)
    assert session.wait_idle(TIMEOUT_MS / 1000)
    for les in LESSONS:
        session.controls["lesson"].value = les.name
        tab = next(v.tab for v in ALL_VIEWS if v.name == les.plot)
        reached = _tab_shown(page, session, tab, click=False)
        _measure(page, session, mode, f"lesson:{les.name}", shots, found, reached)
        found[name][f"lesson:{les.name}"] += _teacher_checks(page, mode, les.name)
    session.controls["lesson"].value = "fig1"  # the tabs as the fig1 lesson shows them
    assert session.wait_idle(TIMEOUT_MS / 1000)
    for tab in TABS:
        reached = _tab_shown(page, session, tab, click=True)
        _measure(page, session, mode, f"tab:{tab}", shots, found, reached)
    _scene_shot(page, session, name, shots)
    system, values = NONLINEAR  # a nonlinear plant chosen by hand, at the panel's defaults for one
    session.controls["lesson"].value = NONE
    assert session.wait_idle(TIMEOUT_MS / 1000)
    session.controls["system"].value = system
    assert session.wait_idle(TIMEOUT_MS / 1000)
    for key, value in values.items():
        session.controls[key].value = value
    reached = _tab_shown(page, session, KOOPMAN_TABS[0], click=False)
    _measure(page, session, mode, f"system:{system}", shots, found, reached)
    if session.last_error is not None or getattr(session.last_frame, "kind", "") != "koopman":
        found[name][f"system:{system}"].append(Problem("none", system, f"no nonlinear frame: {session.last_error}"))


def _open(ctx, app):
    """A new tab of ``app`` in browser context ``ctx``: (page, its session), its first view drawn."""

    def ids() -> set:
        with app._lock:  # tabs connect and leave on the server's threads
            return set(app.sessions)

    page = ctx.new_page()
    before = ids()
    page.goto(app.url, timeout=TIMEOUT_MS)
    wait_until(lambda: ids() - before, "the new tab's session", TIMEOUT_MS / 1000)
    new = max(ids() - before)
    with app._lock:
        session = app.sessions[new]
    assert session.wait_idle(TIMEOUT_MS / 1000)
    page.wait_for_selector("canvas", timeout=TIMEOUT_MS)
    page.wait_for_function("document.querySelectorAll('.js-plotly-plot').length >= 2", timeout=TIMEOUT_MS)
    _dismiss_notices(page)
    return page, session


def _write_report(path: str, found: dict) -> None:
    counts = {name: summary([p for ps in places.values() for p in ps]) for name, places in found.items()}
    text = {name: {place: [str(p) for p in ps] for place, ps in places.items()} for name, places in found.items()}
    with open(path, "w", encoding="utf-8") as f:
        json.dump({"counts": counts, "problems": text}, f, indent=1, ensure_ascii=False)


@pytest.fixture(scope="module")
def measured(lessons_app) -> dict:
    """Every mode walked once in one browser and one server (the lessons' results are computed once; the server
    is the one test_dashboard_drawn_browser.py walks first): mode name -> place -> problems."""
    _require_browser()
    from playwright.sync_api import sync_playwright

    shots = os.environ.get("QSID_SCREENSHOT_DIR")
    report = os.environ.get("QSID_LEGIBILITY_REPORT")
    only = os.environ.get("QSID_LEGIBILITY_MODES")  # e.g. "phone,hd-presenter": a subset while working
    modes = [m for m in MODES if not only or m[0] in only.split(",")]
    found: dict = {}
    app = lessons_app
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
            try:
                for mode in modes:  # each mode a tab of its own opened at its size, as a phone or a projector would
                    ctx = browser.new_context(viewport={"width": mode[1][0], "height": mode[1][1]})
                    try:
                        page, session = _open(ctx, app)
                        _walk(page, session, mode, shots, found)
                    except Exception as exc:  # this mode fails on it; the other modes are still measured
                        found.setdefault(mode[0], {})["walk"] = [Problem("none", mode[0], f"walk failed: {exc!r}")]
                    finally:
                        ctx.close()
            finally:
                browser.close()
    finally:
        if report:  # also what was measured before a failure
            _write_report(report, found)
    return found


@pytest.mark.parametrize("mode", [m[0] for m in MODES])
def test_every_plot_is_legible(measured, mode):
    if mode not in measured:
        pytest.skip(f"{mode} not in QSID_LEGIBILITY_MODES")
    bad = {place: [str(p) for p in ps] for place, ps in measured[mode].items() if ps}
    assert not bad, json.dumps(bad, indent=1, ensure_ascii=False)[:6000]
