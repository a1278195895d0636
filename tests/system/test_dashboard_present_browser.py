"""Class-ready presenting and sharing in headless Chromium (issue 38, part 5): presenter mode at 1366×768 keeps
its slider, auto-play and 3-D switch in the window whatever the lesson; no plotly tool bar (no cloud upload, none
over a title); a note's sentences visible in presenter mode; a follower's number box inert; a phone's dropdown
list on screen. With ``QSID_SHOT_DIR=dir`` the pages are saved there as PNG."""

from __future__ import annotations

import os

import pytest
from support import wait_until
from test_dashboard_browser import ARGS, CHROMIUM, TIMEOUT_MS, _require_browser
from test_dashboard_teach_browser import _dismiss_notices

from app.dashboard.presenter import SHOW_SCENE
from app.figures.presenter import HOVER_HERE
from app.lessons.table import LESSONS

pytestmark = pytest.mark.browser

#: Bottom edge (px) of the first visible element whose text (or value) starts with each given text.
BOTTOMS = """(names) => names.map(n => {
  const e = [...document.querySelectorAll('button, input')].find(e => e.offsetParent !== null
      && ((e.textContent || '').trim().startsWith(n) || (e.tagName === 'INPUT' && e.value === n)));
  return e ? e.getBoundingClientRect().bottom : null;
})"""
#: The word-length slider's number box: [pointer-events, opacity].
BITS_BOX = """() => {
  const uid = [...document.querySelectorAll('label')].find(e => e.textContent.includes('word length b')).htmlFor;
  const box = document.querySelector(`[id='${uid}']`).parentElement.querySelector('.mantine-NumberInput-input');
  const s = getComputedStyle(box.closest('.mantine-NumberInput-root'));
  return [s.pointerEvents, parseFloat(s.opacity), box.value];
}"""
#: Texts of the visible plots' annotations and whether any plotly tool bar is in the page.
PLOT_TEXTS = """() => [[...document.querySelectorAll('.js-plotly-plot')].filter(e => e.offsetParent !== null)
  .flatMap(e => [...e.querySelectorAll('.annotation-text')].map(t => t.textContent)),
  document.querySelectorAll('.modebar-container .modebar-btn').length]"""


def _shot(page, name: str) -> None:
    d = os.environ.get("QSID_SHOT_DIR")
    if d:
        os.makedirs(d, exist_ok=True)
        page.screenshot(path=os.path.join(d, f"{name}.png"))


def _open(ctx, app, url=None):
    def ids() -> set:
        with app._lock:
            return set(app.sessions)

    page, before = ctx.new_page(), ids()
    page.goto(url or app.url, timeout=TIMEOUT_MS)
    wait_until(lambda: ids() - before, "the new tab's session", TIMEOUT_MS / 1000)
    new = max(ids() - before)
    with app._lock:
        session = app.sessions[new]
    page.wait_for_selector("canvas", timeout=TIMEOUT_MS)
    page.wait_for_function("document.querySelectorAll('.js-plotly-plot').length >= 2", timeout=TIMEOUT_MS)
    _dismiss_notices(page)
    return page, session


@pytest.fixture(scope="module")
def chromium():
    _require_browser()
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
        yield b
        b.close()


def test_presenter_mode_at_1366x768_shows_slider_play_and_switch_for_the_longest_lesson(chromium):
    """The switch was below the window in every lesson (bits-needed: the slider and auto-play too)."""
    from app.dashboard import DashboardApp

    longest = max(LESSONS, key=lambda les: len(les.text)).name
    app = DashboardApp(host="127.0.0.1", port=0, workers=0, lesson=longest)
    ctx = chromium.new_context(viewport={"width": 1366, "height": 768})
    try:
        page, session = _open(ctx, app)
        session.controls["presenter"].value = True
        wait_until(lambda: session.presenter.on, "presenter mode applied", TIMEOUT_MS / 1000)
        page.wait_for_function(
            f"[...document.querySelectorAll('button')].some(b => b.textContent.includes('{SHOW_SCENE}'))",
            timeout=TIMEOUT_MS,
        )
        page.wait_for_timeout(1000)  # the panel's new order laid out
        _shot(page, f"presenter-1366-{longest}")
        bits = str(session.controls["bits"].value)
        slider, play, switch = page.evaluate(BOTTOMS, [bits, "▶ auto-play", SHOW_SCENE])
        assert None not in (slider, play, switch), (slider, play, switch)
        assert max(slider, play, switch) <= 768, (longest, slider, play, switch)
    finally:
        ctx.close()
        app.stop()


def test_no_tool_bar_notes_shown_in_presenter_mode_and_a_followers_box_is_inert(chromium):
    from app.dashboard import DashboardApp

    app = DashboardApp(host="127.0.0.1", port=0, workers=0, lesson="bound")  # dc-motor: Theorem 1 faded, a note
    ctx = chromium.new_context(viewport={"width": 1920, "height": 1080})
    try:
        page, session = _open(ctx, app)
        assert session.wait_idle(TIMEOUT_MS / 1000)
        session.views.show("Identification")  # the error plot and its notes
        page.wait_for_function(
            "() => [...document.querySelectorAll('.annotation-text')].some(t => t.textContent.startsWith('Notes:'))",
            timeout=TIMEOUT_MS,
        )
        plot = page.locator(".js-plotly-plot").first
        box = plot.bounding_box()
        page.mouse.move(box["x"] + box["width"] / 2, box["y"] + 40)  # over the title, where the bar was
        page.wait_for_timeout(500)
        texts, buttons = page.evaluate(PLOT_TEXTS)
        assert buttons == 0  # no tool bar: nothing over a title, no "Share chart…"
        assert any(HOVER_HERE in t for t in texts)  # a laptop keeps the one-line note (the hover has the rest)
        session.controls["presenter"].value = True
        wait_until(lambda: session.presenter.on and session.wait_idle(1), "presenter mode drawn", TIMEOUT_MS / 1000)
        page.wait_for_function(
            "() => [...document.querySelectorAll('.annotation-text')].some(t => t.textContent.startsWith('Notes:'))",
            timeout=TIMEOUT_MS,
        )
        page.wait_for_timeout(1000)
        _shot(page, "presenter-1920-bound-notes")
        texts, buttons = page.evaluate(PLOT_TEXTS)
        notes = [t for t in texts if t.startswith("Notes:")]
        assert notes and not any(HOVER_HERE in t for t in notes) and buttons == 0, notes
        follower, _ = _open(ctx, app, app.url.rstrip("/") + f"/f/{session.codes.view.code}")
        follower.wait_for_timeout(1000)
        _shot(follower, "follower-1920")
        events, opacity, value = follower.evaluate(BITS_BOX)
        assert events == "none" and opacity < 1 and value == str(session.controls["bits"].value)
        follower.close()
    finally:
        ctx.close()
        app.stop()


def test_a_phones_show_dropdown_opens_on_screen(chromium):
    from app.dashboard import DashboardApp

    app = DashboardApp(host="127.0.0.1", port=0, workers=0, lesson="bound")
    ctx = chromium.new_context(viewport={"width": 390, "height": 844}, is_mobile=True, has_touch=True)
    try:
        page, session = _open(ctx, app)
        assert session.ui.phone.narrow
        for block in ("center", "nearest"):  # the input mid-sheet, and at the sheet's foot
            uid = page.evaluate(
                """(block) => { const l = [...document.querySelectorAll('label')]
                     .find(e => e.textContent.trim() === 'show');
                   document.getElementById(l.htmlFor).scrollIntoView({block: block}); return l.htmlFor; }""",
                block,
            )
            page.wait_for_timeout(500)
            page.locator(f"[id='{uid}']").tap(force=True)
            page.wait_for_function(
                "[...document.querySelectorAll('.mantine-Select-dropdown')].some(e => e.offsetHeight > 0)",
                timeout=TIMEOUT_MS,
            )
            _shot(page, f"phone-show-dropdown-{block}")
            box = page.evaluate(
                """() => { const e = [...document.querySelectorAll('.mantine-Select-dropdown')]
                  .find(e => e.offsetHeight > 0); const r = e.getBoundingClientRect();
                  return [r.left, r.top, r.right, r.bottom, e.textContent]; }"""
            )
            left, top, right, bottom, text = box
            assert 0 <= left and right <= 390 and 0 <= top and bottom <= 844, box
            assert "Identification" in text and "Compare" in text
            page.keyboard.press("Escape")
            page.wait_for_timeout(300)
    finally:
        ctx.close()
        app.stop()
