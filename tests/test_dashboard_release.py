"""Nothing of a tab is kept once it closes (its session, worker thread, panel and renderer are freed)."""

from __future__ import annotations

import gc
import time
import weakref

from app.dashboard import DashboardApp
from test_dashboard_server import SMALL, Tab


def test_closed_tabs_leave_nothing_behind():
    app = DashboardApp(host="127.0.0.1", port=0, workers=0)
    refs, threads = [], []
    try:
        for _ in range(3):
            t = Tab(app)
            t.set(mpc_steps=15, **SMALL)
            t.wait(120)
            s = t.session
            refs += [weakref.ref(s), weakref.ref(s.renderer), weakref.ref(s.views), weakref.ref(s.portrait)]
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
