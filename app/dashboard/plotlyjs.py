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
"""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path
from typing import Any

from .viserfix import send_plotly_js

__all__ = ["BUNDLE", "TRACE_TYPES", "bundle_version", "send_basic_bundle"]

BUNDLE = Path(__file__).resolve().parent / "assets" / "plotly-basic.min.js"
#: The trace types the basic bundle draws.
TRACE_TYPES = ("scatter", "bar", "pie")


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
    if version != wanted:
        return f"the shipped basic bundle is plotly.js {version or '(missing)'}, plotly needs {wanted}"
    if not send_plotly_js(gui, source):  # viser then skips sending the full bundle
        return "this viser version sends plotly.js differently (or it was sent already)"
    return None
