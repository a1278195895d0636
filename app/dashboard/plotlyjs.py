"""plotly.js for the dashboard's plots: the "basic" bundle (scatter, bar, pie), 1.2 MB instead of 4.8 MB.

Before a tab's first plot, viser sends the plotly package's full ``plotly.min.js``
(4.8 MB) over the tab's websocket, and the browser evaluates it. Headless
Chromium here took ~1.3 s to evaluate the full bundle against ~0.2 s for
plotly.js's official "basic" bundle (the same version, only the trace types
scatter, bar and pie, which are all the dashboard draws; a test checks every
view's traces). :func:`send_basic_bundle` queues that bundle first and tells viser
it is there, so viser does not send its own.

The bundle (``assets/plotly-basic.min.js``, npm ``plotly.js-basic-dist-min``, MIT
licence beside it) is used only when its version equals the plotly.js version the
installed plotly package was built for; otherwise viser's own bundle is sent as before.
To update it: ``npm pack plotly.js-basic-dist-min@<plotly.offline.get_plotlyjs_version()>``.

Whichever bundle goes, :data:`ZERO_WIDTH_GUARD` follows it: viser's plot element draws once at width 0 when it
appears (before its size is measured), and plotly then falls back to 700 × 450 px; a figure whose margins need
more than 450 px (presenter mode and phones write their notes out above the plot) makes plotly throw "Something
went wrong with axis scaling", which takes viser's whole page down (docs/known-issues.rst). The guard skips a
draw at width 0; the element draws again once measured.
"""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path
from typing import Any

from .viserfix import send_plotly_js

__all__ = ["BUNDLE", "TRACE_TYPES", "ZERO_WIDTH_GUARD", "bundle_version", "send_basic_bundle"]

BUNDLE = Path(__file__).resolve().parent / "assets" / "plotly-basic.min.js"
#: The trace types the basic bundle draws.
TRACE_TYPES = ("scatter", "bar", "pie")
#: Run after plotly.js: ``Plotly.react`` with a layout 0 px wide draws nothing (see the module's docstring).
ZERO_WIDTH_GUARD = (
    "\n;(function(P){if(!P||P.__qsidGuard)return;var react=P.react;"
    "P.react=function(gd,data,layout,config){if(layout&&layout.width===0)return Promise.resolve(gd);"
    "return react.call(this,gd,data,layout,config);};P.__qsidGuard=true;})(window.Plotly);\n"
)


@lru_cache(maxsize=1)
def _bundle() -> tuple[str, str]:
    """(version, source) of the shipped basic bundle; ("", "") if it is missing."""
    try:
        text = BUNDLE.read_text(encoding="utf-8")
    except OSError:
        return "", ""
    return bundle_version(text), text


def bundle_version(source: str) -> str:
    """The version in a plotly.js bundle's banner ("plotly.js (basic - minified) v4.1.1" -> "4.1.1")."""
    m = re.search(r"plotly\.js[^\n]*?v(\d+\.\d+\.\d+)", source[:400])
    return m.group(1) if m else ""


def send_basic_bundle(gui: Any) -> str | None:
    """Queue the basic bundle to the tab of ``gui`` (a ``client.gui``) before its first plot.

    Returns None when it was sent, else why viser's own bundle will be sent instead.
    Call it before the tab's first ``add_plotly``.
    """
    import plotly.offline

    version, source = _bundle()
    wanted = plotly.offline.get_plotlyjs_version()
    note = None
    if version != wanted:  # the full bundle, as viser would send it, with the guard
        note = f"the shipped basic bundle is plotly.js {version or '(missing)'}, plotly needs {wanted}"
        source = plotly.offline.get_plotlyjs()
    if not send_plotly_js(gui, source + ZERO_WIDTH_GUARD):  # viser then skips sending its own bundle
        return "this viser version sends plotly.js differently (or it was sent already)"
    return note
