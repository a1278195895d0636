"""The first screen in headless Chromium: ``qsid-dashboard`` as started with no option opens on the guided start,
whose whole text, with the letter's arXiv link, and the word-length slider below it are on screen at 1366 × 768
without scrolling. With ``QSID_SCREENSHOT_DIR=assets`` the picture of docs/getting-started.rst is written there
(``start-laptop.png``)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from test_dashboard_browser import ARGS, CHROMIUM, TIMEOUT_MS, _require_browser
from test_dashboard_teach_browser import _dismiss_notices

from app.lessons.start import LETTER_URL, START

pytestmark = pytest.mark.browser

#: The start text's box, the word-length slider's and the window's height (the deepest element holding the text).
BOXES = """() => {
  const all = [...document.querySelectorAll('div, p')].filter(
    e => e.textContent.includes('Start here.') && e.textContent.includes('glossary.html'));
  if (!all.length) return null;
  const text = all.reduce((a, b) => (b.textContent.length < a.textContent.length ? b : a));
  const label = [...document.querySelectorAll('label')].find(l => l.textContent.trim() === 'word length b');
  const slider = label && document.getElementById(label.getAttribute('for'));
  const box = e => { const r = e.getBoundingClientRect(); return [r.top, r.bottom, r.left, r.right]; };
  const links = [...text.querySelectorAll('a')].map(a => a.href);
  return {text: box(text), slider: slider ? box(slider) : null, height: window.innerHeight,
          width: window.innerWidth, links};
}"""


def test_the_first_screen_shows_the_whole_start_text_and_the_slider_at_1366x768(tmp_path):
    _require_browser()
    from playwright.sync_api import sync_playwright

    from app.dashboard import DashboardApp
    from app.dashboard.options import read_options

    args = read_options(["--port", "0"])[0]  # what `qsid-dashboard` with no option opens on
    assert args.lesson == START
    app = DashboardApp(host="127.0.0.1", port=0, workers=0, lesson=args.lesson)
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
            try:
                page = browser.new_context(viewport={"width": 1366, "height": 768}).new_page()
                page.goto(app.url, timeout=TIMEOUT_MS)
                session = app.wait_for_sessions(1, timeout=TIMEOUT_MS / 1000)[0]
                assert session.wait_idle(TIMEOUT_MS / 1000)
                page.wait_for_function(f"({BOXES})() !== null", timeout=TIMEOUT_MS)
                page.wait_for_function("document.querySelectorAll('.js-plotly-plot').length >= 1", timeout=TIMEOUT_MS)
                _dismiss_notices(page)
                got = page.evaluate(BOXES)
                top, bottom, left, right = got["text"]
                assert 0 <= top and bottom <= got["height"] and 0 <= left and right <= got["width"], got
                assert got["slider"] is not None and got["slider"][1] <= got["height"], got  # the slider to move first
                assert LETTER_URL in got["links"], got["links"]  # the letter, one click away
                shot = tmp_path / "start-laptop.png"
                page.screenshot(path=str(shot), timeout=TIMEOUT_MS)
                if os.environ.get("QSID_SCREENSHOT_DIR"):
                    shutil.copyfile(shot, Path(os.environ["QSID_SCREENSHOT_DIR"]) / "start-laptop.png")
            finally:
                browser.close()
    finally:
        app.stop()
