"""viser's plot element draws once at width 0 when it appears; plotly then falls back to 700 × 450 px, and a figure
whose margins need more than that (presenter mode and phones write their notes out) throws, which took the whole
page down in presenter mode. :data:`app.dashboard.viewpanel.ZERO_WIDTH_GUARD` skips that draw: checked here in
Chromium on the very call viser makes, with and without the guard (the test of the guard can fail)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from test_dashboard_browser import ARGS, CHROMIUM, _require_browser

from app.dashboard.viewpanel import BUNDLE, ZERO_WIDTH_GUARD

pytestmark = pytest.mark.browser

#: Presenter mode's error plot in the data-length lesson as the page received it (recorded; the layout's keys that
#: do not matter left out): a top margin of 404 px for its notes, the legend at the container's foot.
FIGURE = json.loads((Path(__file__).parent / "zero_width_figure.json").read_text(encoding="utf-8"))
#: What viser's PlotWithAspect does on mount, before its size is measured, then once measured (972 px wide).
MOUNT = """async ([fig, width]) => {
  const gd = document.getElementById('g');
  Plotly.purge(gd);
  await Plotly.react(gd, fig.data, {...fig.layout, width: 0, height: 0});
  await Plotly.react(gd, fig.data, {...fig.layout, width: width, height: width * 0.944});
  return gd.querySelectorAll('.scatterlayer .trace').length;
}"""


def _page_errors(guard: bool) -> tuple[list[str], int | None]:
    import plotly.io as pio
    from playwright.sync_api import Error, sync_playwright

    figure = {**FIGURE, "layout": {**FIGURE["layout"], "template": pio.templates["plotly_white"].to_plotly_json()}}

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
        try:
            page = browser.new_page()
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.set_content("<div style='width:972px'><div id=g></div></div>")
            page.add_script_tag(content=BUNDLE.read_text(encoding="utf-8") + (ZERO_WIDTH_GUARD if guard else ""))
            try:
                traces = page.evaluate(MOUNT, [figure, 972])
            except Error as exc:
                errors.append(str(exc))
                traces = None
            return errors, traces
        finally:
            browser.close()


def test_the_first_draw_at_width_0_throws_without_the_guard_and_is_skipped_with_it():
    _require_browser()
    errors, _ = _page_errors(guard=False)
    assert any("axis scaling" in e for e in errors), errors  # what took presenter mode's page down
    errors, traces = _page_errors(guard=True)
    assert errors == [] and traces and traces >= len(FIGURE["data"])  # drawn once measured
