"""The data plotly draws in a real headless Chromium, checked by :func:`drawn.check_drawn`: for the dashboard's
default view, every group of the "show" dropdown is picked as a person picks it and every visible plot's
``el.data`` (what plotly.js holds, read from the page) must be consistent (x and y equally long, every band
enclosing its line), and the Control group's ‖x_t‖ band must equal the server's figure."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from drawn import band_edges, check_drawn, traces, values

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--no-first-run", "--disable-sync"]
TIMEOUT_MS = 300_000  # a hang guard for every wait, not a speed target

pytestmark = [pytest.mark.browser, pytest.mark.slow]

#: Every visible plot's traces as plotly.js holds them (arrays copied out of typed arrays).
VISIBLE_DATA = """() => [...document.querySelectorAll('.js-plotly-plot')]
  .filter(e => e.offsetParent !== null && Array.isArray(e.data))
  .map(e => ({
    title: (e.data.find(t => t.name) || {}).name || e.textContent.slice(0, 60),
    data: e.data.map(t => {
      const o = {};
      for (const [k, v] of Object.entries(t)) {
        if (ArrayBuffer.isView(v)) o[k] = Array.from(v);
        else if (['x', 'y', 'text', 'fill', 'mode', 'name', 'legendgroup', 'xaxis', 'yaxis', 'type',
                  'error_y', 'error_x'].includes(k)) o[k] = v;
      }
      return o;
    }),
  }))"""


def _require_browser():
    if not Path(CHROMIUM).exists():
        pytest.skip(f"{CHROMIUM} is missing (apt-get install chromium); CI installs it")
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        pytest.skip("the playwright Python package is missing (pip install playwright)")


def _pick(page, label: str, count: int) -> list[dict]:
    """Pick group ``label`` in the "show" dropdown; wait until ``count`` plots are visible and drawn."""
    page.get_by_label("show", exact=True).click(timeout=TIMEOUT_MS)
    page.get_by_role("option", name=label, exact=True).click(timeout=TIMEOUT_MS)
    page.wait_for_function(
        f"() => ({VISIBLE_DATA})().length === {count} && ({VISIBLE_DATA})().every(p => p.data.length > 0)",
        timeout=TIMEOUT_MS,
    )
    return page.evaluate(VISIBLE_DATA)


def test_every_plot_of_the_default_view_draws_consistent_data_in_the_browser():
    _require_browser()
    from playwright.sync_api import sync_playwright

    from app.dashboard import DashboardApp
    from app.figures.registry import TABS, VIEWS

    app = DashboardApp(host="127.0.0.1", port=0, workers=0)
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
            try:
                page = browser.new_page(viewport={"width": 1366, "height": 768})
                page.goto(app.url, timeout=TIMEOUT_MS)
                session = app.wait_for_sessions(1, timeout=TIMEOUT_MS / 1000)[0]
                assert session.wait_idle(TIMEOUT_MS / 1000)
                page.wait_for_selector("canvas", timeout=TIMEOUT_MS)
                page.wait_for_function("document.querySelectorAll('.js-plotly-plot').length >= 2", timeout=TIMEOUT_MS)
                checked = 0
                for label in TABS:
                    if label == "Data length":  # drawn on demand (a button): nothing to check until pressed
                        continue
                    plots = _pick(page, label, sum(v.tab == label for v in VIEWS))
                    for p in plots:
                        check_drawn(p["data"], f"browser, {label}: {p['title']!r}")
                        checked += 1
                    if label == "Control":  # the band as the browser has it is the server's
                        norm = next(
                            p["data"] for p in plots if any("‖x_t‖ (median" in (t.get("name") or "") for t in p["data"])
                        )
                        server = traces(session.plots["norm_time"].figure)
                        for mine, theirs in zip(
                            (t for t in norm if t.get("fill")), (t for t in server if t.get("fill"))
                        ):
                            x, hi, lo = band_edges(mine)
                            sx, shi, slo = band_edges(theirs)
                            assert len(values(mine["x"])) == len(values(mine["y"])) == 2 * len(x)
                            np.testing.assert_allclose(hi, shi, rtol=1e-12)
                            np.testing.assert_allclose(lo, slo, rtol=1e-12)
                assert checked == sum(v.tab != "Data length" for v in VIEWS)
            finally:
                browser.close()
    finally:
        app.stop()
