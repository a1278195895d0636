"""A follow link with two real browsers (headless Chromium, two browser contexts): a teacher and a student.

The teacher's tab opens at the bare address (the server redirects it to an address holding its code); the
student opens the follow link shown in the teacher's panel. The teacher moves b in the page and picks a lesson:
the student's page shows the same b, lesson and status. The student's inputs are disabled: pressing keys on
its b slider changes nothing anywhere. "explore from here" makes the student's tab a view of its own: its
changes stay there, and a reload of it comes back to them. The follower is looked at in the sizes a class
uses (1366×768, 1920×1080 with presenter mode, 390×844); with ``QSID_SCREENSHOT_DIR=assets`` the pictures of
docs/class.rst are written there (:data:`SHOTS`).
"""

from __future__ import annotations

import os

import pytest
from support import SMALL, wait_until
from test_dashboard_browser import ARGS, CHROMIUM, TIMEOUT_MS, _require_browser
from test_dashboard_teach_browser import ACTIVE_TAB, BITS_THUMB, _dismiss_notices

from app.dashboard.follow import EXPLORE
from app.figures.registry import VIEWS
from app.lessons.table import get_lesson

pytestmark = pytest.mark.browser

#: Screenshots written with QSID_SCREENSHOT_DIR: (viewport, presenter mode) -> file name.
SHOTS = {
    ((390, 844), False): "follow-phone.png",
    ((1366, 768), False): "follow-laptop.png",
    ((1920, 1080), True): "follow-hd-presenter.png",
}
#: The text of the page (panels, not plots): what a person reads.
TEXT = "() => document.body.innerText"


def _newest(app, before: set):
    with app._lock:  # tabs connect and leave on the server's threads
        new = [s for cid, s in app.sessions.items() if cid not in before]
    return new[0] if new else None


def _open(ctx, app, url):
    """A page at ``url`` and its session, its first view drawn."""
    with app._lock:
        before = set(app.sessions)
    page = ctx.new_page()
    page.goto(url, timeout=TIMEOUT_MS)
    wait_until(lambda: _newest(app, before) is not None, "the tab's session")
    session = _newest(app, before)
    assert session.wait_idle(TIMEOUT_MS / 1000)
    page.wait_for_selector("canvas", timeout=TIMEOUT_MS)
    page.wait_for_function("document.querySelectorAll('.js-plotly-plot').length >= 2", timeout=TIMEOUT_MS)
    return page, session


def _bits_shown(page) -> int:
    return int(page.evaluate(BITS_THUMB))


def _press_bits(page, key: str, times: int) -> None:
    """Keys on the word-length slider, as a person using the keyboard (a disabled slider takes none)."""
    uid = page.evaluate(
        "() => [...document.querySelectorAll('label')].find(e => e.textContent.includes('word length b')).htmlFor"
    )
    thumb = page.locator(f"[id='{uid}'] [role=slider]").first
    thumb.focus()
    for _ in range(times):
        thumb.press(key)


def _follows(page, teacher, b: int, lesson: str) -> None:
    """The follower's page shows b, the lesson's text and the plots group the teacher's tab shows."""
    page.wait_for_function(f"({BITS_THUMB})() === '{b}'", timeout=TIMEOUT_MS)
    page.wait_for_function(f"() => document.body.innerText.includes('b = {b} drawn')", timeout=TIMEOUT_MS)
    if lesson != "none":
        title = get_lesson(lesson).title
        page.wait_for_function(f"() => document.body.innerText.includes({title[:30]!r})", timeout=TIMEOUT_MS)
    page.wait_for_function(f"({ACTIVE_TAB})() === {teacher.views.shown!r}", timeout=TIMEOUT_MS)


def _shoot(page, size, presenter: bool, shots: str | None) -> None:
    if shots and (size, presenter) in SHOTS:
        _dismiss_notices(page)
        page.wait_for_timeout(800)  # plotly lays the figures out
        page.screenshot(path=os.path.join(shots, SHOTS[(size, presenter)]))


def test_a_student_follows_the_teacher_read_only_then_explores_from_there():
    _require_browser()
    from playwright.sync_api import sync_playwright

    from app.dashboard import DashboardApp
    from app.settings.values import Values

    shots = os.environ.get("QSID_SCREENSHOT_DIR")
    app = DashboardApp(host="127.0.0.1", port=0, workers=1, settings=Values(mpc_steps=30, **SMALL))
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
            try:
                teacher_ctx = browser.new_context(viewport={"width": 1366, "height": 768})
                page, teacher = _open(teacher_ctx, app, app.url)
                code = teacher.codes.view.code
                # the server put the tab's code in its address: no script rewrote it
                assert f"/n/{code}/" in page.evaluate("() => location.search")
                follow = f"http://127.0.0.1:{app.port}/f/{code}"  # shown as it is written on the board
                assert (
                    page.get_by_role("link", name=follow.removeprefix("http://")).first.get_attribute("href") == follow
                )

                student_ctx = browser.new_context(viewport={"width": 1366, "height": 768})
                spage, student = _open(student_ctx, app, follow)
                assert student.codes.view.follow == code
                assert f"/f/{code}/" in spage.evaluate("() => location.search")
                spage.wait_for_function(
                    f"() => document.body.innerText.includes('Following view {code} live')", timeout=TIMEOUT_MS
                )
                page.wait_for_function("() => document.body.innerText.includes('1 following')", timeout=TIMEOUT_MS)

                # the teacher moves b in the page, then picks a lesson: the student sees the same
                b0 = _bits_shown(page)
                _press_bits(page, "ArrowRight", 2)
                page.wait_for_function(f"({BITS_THUMB})() === '{b0 + 2}'", timeout=TIMEOUT_MS)
                # the page shows the thumb moved at once; the value reaches the server a moment later
                wait_until(lambda: teacher.last_frame.values.bits == b0 + 2, "the teacher's tab drawn at the new b")
                assert teacher.wait_idle(TIMEOUT_MS / 1000) and teacher.last_frame.values.bits == b0 + 2
                _follows(spage, teacher, b0 + 2, "none")
                teacher.controls["lesson"].value = "dither"
                assert teacher.wait_idle(TIMEOUT_MS / 1000)
                b1 = teacher.last_frame.values.bits
                tab = next(v.tab for v in VIEWS if v.name == get_lesson("dither").plot)
                page.wait_for_function(f"({ACTIVE_TAB})() === {tab!r}", timeout=TIMEOUT_MS)
                _follows(spage, teacher, b1, "dither")
                assert student.wait_idle(TIMEOUT_MS / 1000)
                assert student.ui.panel_values() == teacher.ui.panel_values()
                _shoot(spage, (1366, 768), False, shots)

                # the student's b slider is disabled: its keys change nothing, here or at the teacher's
                _press_bits(spage, "ArrowLeft", 3)
                spage.wait_for_timeout(1500)
                assert _bits_shown(spage) == b1 and _bits_shown(page) == b1
                assert teacher.wait_idle(TIMEOUT_MS / 1000) and teacher.last_frame.values.bits == b1
                assert app.views.get(code).bits == b1

                # the same follower on a phone, and in presenter mode on a projector
                for size, presenter in (((390, 844), False), ((1920, 1080), True)):
                    if presenter:
                        teacher.controls["presenter"].value = True
                        assert teacher.wait_idle(TIMEOUT_MS / 1000)
                    ctx = browser.new_context(viewport={"width": size[0], "height": size[1]})
                    other, seen = _open(ctx, app, follow)
                    _follows(other, teacher, b1, "dither")
                    assert seen.wait_idle(TIMEOUT_MS / 1000) and seen.ui.panel_values().presenter == presenter
                    assert other.get_by_role("button", name=EXPLORE).first.is_visible()
                    _shoot(other, size, presenter, shots)
                    ctx.close()
                teacher.controls["presenter"].value = False
                assert teacher.wait_idle(TIMEOUT_MS / 1000)
                _follows(spage, teacher, b1, "dither")

                # "explore from here": the student's own view, from the teacher's settings at that moment
                spage.get_by_role("button", name=EXPLORE).first.click()
                spage.wait_for_function(
                    "() => document.body.innerText.includes('This tab is now your own view')", timeout=TIMEOUT_MS
                )
                wait_until(lambda: not student.follower.active, "the student explored")
                own = student.codes.view.code
                assert own != code and student.codes.view.kept
                assert student.wait_idle(TIMEOUT_MS / 1000)
                _press_bits(spage, "ArrowRight", 2)
                spage.wait_for_function(f"({BITS_THUMB})() === '{b1 + 2}'", timeout=TIMEOUT_MS)
                wait_until(lambda: student.last_frame.values.bits == b1 + 2, "the student's tab drawn at the new b")
                assert student.wait_idle(TIMEOUT_MS / 1000) and student.last_frame.values.bits == b1 + 2
                assert teacher.wait_idle(TIMEOUT_MS / 1000) and teacher.last_frame.values.bits == b1
                assert _bits_shown(page) == b1 and app.views.get(code).bits == b1

                # a reload of the student's tab comes back to the student's view (its address names that code)
                with app._lock:
                    before = set(app.sessions)
                spage.reload(timeout=TIMEOUT_MS)
                wait_until(lambda: _newest(app, before) is not None, "the reloaded tab")
                again = _newest(app, before)
                assert again.wait_idle(TIMEOUT_MS / 1000)
                assert again.follower is None and again.codes.view.code == own
                assert again.last_frame.values.bits == b1 + 2 and again.last_frame.values.lesson == "dither"
                spage.wait_for_function(f"({BITS_THUMB})() === '{b1 + 2}'", timeout=TIMEOUT_MS)
            finally:
                browser.close()
    finally:
        app.stop()
