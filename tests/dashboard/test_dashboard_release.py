"""Nothing of a tab is kept once it closes (its session, worker thread, panel and renderer are freed)."""

from __future__ import annotations

import gc
import time
import weakref

import pytest
from support import SMALL, Tab

from app.dashboard import DashboardApp


# slow (~6 s): three tabs computed, closed and collected one after the other
@pytest.mark.slow
def test_closed_tabs_leave_nothing_behind():
    app = DashboardApp(host="127.0.0.1", port=0, workers=0)
    refs, threads = [], []
    try:
        for _ in range(3):
            t = Tab(app)
            t.set(mpc_steps=15, **SMALL)
            t.wait(120)
            s = t.session
            refs += [weakref.ref(x) for x in (s, s.ui, s.ui.renderer, s.views, s.portrait)]
            threads.append(s.thread)
            t.close()
            del t, s
            end = time.monotonic() + 60
            while app.sessions and time.monotonic() < end:
                time.sleep(0.1)
        for th in threads:
            th.join(60)
        end = time.monotonic() + 60  # viser's callback threads may hold a closed tab a moment longer
        while any(r() is not None for r in refs) and time.monotonic() < end:
            gc.collect()
            time.sleep(0.2)
        assert not app.sessions and not any(th.is_alive() for th in threads)
        left = [r() for r in refs if r() is not None]
        assert left == [], [(type(o).__name__, [type(x).__name__ for x in gc.get_referrers(o)][:8]) for o in left]
    finally:
        app.stop()


def test_max_tabs_refuses_a_further_tab_with_a_page_message_and_frees_the_place_on_close():
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from _wsclient import WsTab

    app = DashboardApp(host="127.0.0.1", port=0, workers=0, max_tabs=1)
    first = extra = again = None
    try:
        first = Tab(app)
        extra = WsTab(app.url)
        end = time.monotonic() + 60
        while time.monotonic() < end and not any("dashboard is full" in m for m in extra.markdown.values()):
            time.sleep(0.1)
        assert any("at most 1 tab(s)" in m for m in extra.markdown.values()), extra.markdown
        assert len(app.sessions) == 1
        extra.close()
        first.close()
        end = time.monotonic() + 60
        while (app.sessions or app._admitted) and time.monotonic() < end:
            time.sleep(0.1)
        again = Tab(app)  # the place is free again
        assert len(app.sessions) == 1
    finally:
        for t in (first, extra, again):
            if t is not None:
                t.close()
        app.stop()
