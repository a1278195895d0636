"""A tab closed in the middle of a draw: the draw's messages are dropped without viser's "closed connection"
warning."""

from __future__ import annotations

import time
import warnings

import pytest
from support import HANG_S, SMALL, Tab

# slow: an in-process server and a websocket tab
pytestmark = pytest.mark.slow


def test_a_tab_closed_mid_draw_leaves_no_warning():
    from app.dashboard import DashboardApp

    app = DashboardApp(host="127.0.0.1", port=0, workers=0)
    try:
        tab = Tab(app)
        tab.set(**SMALL)
        ui, session = tab.session.ui, tab.session
        draw, late = ui.draw, []

        def closing_draw(frame, stale):
            """The tab closes right after the worker's last check: the draw goes to a closed connection."""
            if not late:
                tab.close()
                end = time.monotonic() + HANG_S
                while session.client.client_id in app.sessions and time.monotonic() < end:
                    time.sleep(0.01)
                late.append(session.client.client_id not in app.sessions)
            return draw(frame, lambda: False)

        ui.draw = closing_draw
        with warnings.catch_warnings(record=True) as got:
            warnings.simplefilter("default")
            drop_filters = [f for f in warnings.filters if "closed connection" in str(f[1])]
            assert drop_filters, "the dashboard installs its filter"
            warnings.filters[:] = drop_filters + [f for f in warnings.filters if f not in drop_filters]
            tab.controls["bits"].value = 5  # a new b: the draw sends new figures and a new scene
            session.thread.join(HANG_S)  # the worker ends at its next check after the draw
            assert late == [True]  # the draw really went to a closed connection
        assert not [w for w in got if "closed connection" in str(w.message)], [str(w.message) for w in got]
    finally:
        app.stop()
