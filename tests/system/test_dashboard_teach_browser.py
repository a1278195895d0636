"""A teacher's session in headless Chromium: presenter mode from the server's flag, auto-play, reload, links.

At 1366×768 with presenter mode on (``qsid-dashboard --presenter``) and at 1920×1080 with it off: the new tab's
plot text is in its mode's size; auto-play runs a few word lengths, a reload brings the tab's settings back, and
the tab's link opened in a second page shows the same settings under a code of its own. Every lesson at these
sizes (its key plot above the fold, presenter mode's text and plot sizes) is checked by
``test_dashboard_legibility.py``, which opens each lesson once per mode on one server. With
``QSID_SCREENSHOT_DIR=assets`` the auto-play screenshot of docs/teaching.rst is written there."""

from __future__ import annotations

import os

import pytest
from support import wait_until
from test_dashboard_browser import ARGS, CHROMIUM, TIMEOUT_MS, _require_browser

import app.dashboard.presenter as presenter_module
from app.figures.presenter import PLOT_FONT
from app.figures.registry import ALL_VIEWS
from app.lessons.table import LESSONS, get_lesson
from app.settings.viewcodes import view_link

pytestmark = pytest.mark.browser

#: Smallest font size (px) of the visible plots' text, and how many text elements there are.
PLOT_TEXT = """() => {
  let min = 1e9, n = 0;
  for (const e of document.querySelectorAll('.js-plotly-plot text')) {
    if (!e.textContent.trim() || e.closest('.js-plotly-plot').offsetParent === null) continue;
    if (e.closest('.hoverlayer')) continue;  // a hover label under the mouse is not the plot's text
    const r = e.getBoundingClientRect();
    if (r.width === 0) continue;
    min = Math.min(min, parseFloat(getComputedStyle(e).fontSize)); n++;
  }
  return [min, n];
}"""
#: Smallest font size (px) of visible text in the panels (outside plots and the 3-D canvas).
PANEL_TEXT = """() => {
  let min = 1e9, what = '';
  for (const e of document.querySelectorAll('body *')) {
    if (e.closest('svg') || e.closest('canvas') || e.closest('.mantine-Notification-root') || e.offsetParent === null)
      continue;
    if (![...e.childNodes].some(n => n.nodeType === 3 && n.textContent.trim())) continue;
    const f = parseFloat(getComputedStyle(e).fontSize);
    if (f < min) { min = f; what = e.textContent.trim().slice(0, 40); }
  }
  return [min, what];
}"""
#: Width (px) of the widest visible plot (presenter mode: the key plot).
KEY_PLOT_WIDTH = """() => Math.max(...[...document.querySelectorAll('.js-plotly-plot')]
  .filter(e => e.offsetParent !== null).map(e => e.getBoundingClientRect().width))"""
#: Top (px) of the topmost visible plot in the plots panel.
TOP_PLOT = """() => Math.min(...[...document.querySelectorAll('.js-plotly-plot')]
  .filter(e => e.offsetParent !== null).map(e => e.getBoundingClientRect().top))"""
#: The word-length slider's position in the page.
BITS_THUMB = """() => {
  const uid = [...document.querySelectorAll('label')].find(e => e.textContent.includes('word length b')).htmlFor;
  const t = document.querySelector(`[id='${uid}'] [role=slider]`);
  return t ? t.getAttribute('aria-valuenow') : null;
}"""
#: The group the plots panel shows (the value of its "show" dropdown).
ACTIVE_TAB = """() => {
  const label = [...document.querySelectorAll('label')].find(e => e.textContent.trim() === 'show');
  const input = label && document.getElementById(label.htmlFor);
  return input ? input.value : null;
}"""


def _dismiss_notices(page) -> None:
    """Close the notifications shown, the last first (closing one renumbers those after it); one that
    closed itself meanwhile is skipped."""
    from playwright.sync_api import Error

    close = page.locator(".mantine-Notification-closeButton")
    for i in reversed(range(close.count())):
        try:
            close.nth(i).click(timeout=5_000)
        except Error:
            pass


def _newest(app):
    with app._lock:  # tabs connect and leave on the server's threads
        return max(app.sessions.values(), key=lambda s: s.client.client_id, default=None)


def _open(ctx, app, url, count):
    page = ctx.new_page()
    page.goto(url, timeout=TIMEOUT_MS)
    app.wait_for_sessions(count, timeout=TIMEOUT_MS / 1000)
    session = _newest(app)
    assert session.wait_idle(TIMEOUT_MS / 1000)
    page.wait_for_selector("canvas", timeout=TIMEOUT_MS)
    page.wait_for_function("document.querySelectorAll('.js-plotly-plot').length >= 2", timeout=TIMEOUT_MS)
    return page, session


@pytest.mark.parametrize("size,presenter", [((1366, 768), True), ((1920, 1080), False)])
def test_teacher_walkthrough(size, presenter, monkeypatch):
    _require_browser()
    from playwright.sync_api import sync_playwright

    from app.dashboard import DashboardApp

    shots = os.environ.get("QSID_SCREENSHOT_DIR")
    app = DashboardApp(host="127.0.0.1", port=0, workers=2, presenter=presenter, cache_bytes=1024 * 2**20)
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
            try:
                ctx = browser.new_context(viewport={"width": size[0], "height": size[1]})
                page, s = _open(ctx, app, app.url, 1)
                _dismiss_notices(page)
                code = s.codes.view.code
                # the server redirected the page to an address holding the tab's code (a reload comes back to it)
                assert f"/n/{code}/" in page.evaluate("() => location.search")
                assert page.locator(f"text=view code {code}").count() >= 1
                # the server's presenter flag reaches a new tab: its values, and its plots' text size
                assert s.last_frame.values.presenter == presenter
                page.wait_for_timeout(700)  # plotly lays the figures out
                small, n = page.evaluate(PLOT_TEXT)
                assert n > 0 and (small >= PLOT_FONT if presenter else small < PLOT_FONT), small

                # auto-play: a few word lengths, one after the other, each drawn before the next
                s.controls["lesson"].value = "bound"
                assert s.wait_idle(TIMEOUT_MS / 1000)
                drawn: list = []
                draw = s._draw

                def spy(frame, gen):  # the b of every frame the tab draws
                    ok = draw(frame, gen)
                    if ok and frame.stage == "current":
                        drawn.append(frame.bits)
                    return ok

                s._draw = spy
                # a slower play here (3 s a step): the page must not reach b = 16 before the test presses pause
                monkeypatch.setattr(presenter_module, "STEP_SECONDS", 3.0)
                page.get_by_role("button", name="auto-play").first.click()
                page.wait_for_function(f"() => Number(({BITS_THUMB})()) >= 3", timeout=TIMEOUT_MS)
                wait_until(lambda: 3 in drawn, "b = 3 drawn")
                assert drawn[drawn.index(1) :][:3] == [1, 2, 3] and s.play.state == "playing", drawn
                page.get_by_role("button", name="pause auto-play").click(timeout=TIMEOUT_MS)
                page.wait_for_function(
                    "() => [...document.querySelectorAll('button')].some(b => b.textContent.includes('resume'))",
                    timeout=TIMEOUT_MS,
                )
                if shots and presenter:
                    _dismiss_notices(page)
                    page.wait_for_timeout(500)
                    page.screenshot(path=os.path.join(shots, "teach-autoplay.png"))
                assert s.wait_idle(TIMEOUT_MS / 1000)
                b_paused = s.last_frame.bits
                assert s.play.state == "paused" and 3 <= b_paused < 16

                # reload: the same tab's settings come back (a new session at the same code)
                before = s.client.client_id
                page.reload(timeout=TIMEOUT_MS)
                page.wait_for_function(
                    f"() => document.body.textContent.includes('view code {code}')", timeout=TIMEOUT_MS
                )
                # the reloaded page's panel can show before the server has filed the new tab's session
                wait_until(
                    lambda: (
                        getattr(_newest(app), "client", None) is not None and _newest(app).client.client_id != before
                    ),
                    "the reloaded tab",
                )
                again = _newest(app)
                assert again.codes.view.code == code
                assert again.wait_idle(TIMEOUT_MS / 1000)
                v = again.last_frame.values
                assert (v.bits, v.lesson, v.presenter) == (b_paused, "bound", presenter)

                # the link handed to a class: a second page opens the same settings under a code of its own
                # (the teacher's tab is open: nothing done there may change the teacher's view)
                link = view_link(f"127.0.0.1:{app.port}", code, short=True)
                assert link in again.codes.line.content
                page2, other = _open(ctx, app, link, 2)
                assert other.codes.view.code != code and other.last_frame.values.bits == b_paused
                # its address names its own code (the spare the server handed out with the link)
                assert f"/v/{code}/{other.codes.view.code}" in page2.evaluate("() => location.search")
                assert other.last_frame.values.lesson == "bound"
                page2.wait_for_function(
                    f"() => document.body.textContent.includes('b = {b_paused} drawn')", timeout=TIMEOUT_MS
                )
                page2.close()
            finally:
                browser.close()
    finally:
        app.stop()


def test_every_lesson_names_a_plot_of_the_registry():
    names = {v.name for v in ALL_VIEWS}
    assert all(get_lesson(les.name).plot in names for les in LESSONS)
