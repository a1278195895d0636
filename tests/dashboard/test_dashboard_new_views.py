"""The plots panel's tabs and views on a real server (the ``Tab`` client of test_dashboard_server):
time series, quantizer, data length, pin/compare, tracking and the state box. Each test sets
inputs as a person would and asserts what the views then show."""

from __future__ import annotations

import numpy as np
from support import HANG_S, open_tab

from app.figures.registry import TABS, VIEWS


def fig(tab, name):
    return tab.session.plots[name].figure


def test_views_sit_in_tabs_in_order_and_the_panel_is_wide(tab):
    assert TABS[0] == "Identification" and {v.tab for v in VIEWS} == set(TABS)
    assert [v.name for v in VIEWS if v.tab == "Control"][0] == "timeseries"  # current-b view first
    assert tab.session.plots_panel is not None and tab.session.views.channel.options[0] == "x: angle"


def test_time_series_follow_the_input_bound_and_count_saturation(tab):
    f = fig(tab, "timeseries")
    assert "saturated" in f.layout.title.text and "0 steps" in f.layout.title.text
    assert sorted(abs(s.y0) for s in f.layout.shapes) == [1.0] * 4  # ±u_max on the two input rows
    tab.set(u_max=0.05)
    f2 = fig(tab, "timeseries")
    assert f2 is not f and sorted({abs(s.y0) for s in f2.layout.shapes}) == [0.05]
    k = int(f2.layout.title.text.split("LS ")[1].split(" steps")[0])
    assert k > 0 and "saturated inputs" in tab.summary and f"LS {k} steps" in tab.summary
    u = np.array([y for tr in f2.data if tr.yaxis == "y4" and tr.name == "LS" for y in tr.y if np.isfinite(y)])
    assert u.size and np.abs(u).max() <= 0.05 + 1e-9  # the inputs drawn stay inside the drawn bound


def test_tracking_reference_and_state_box_reach_the_loops(tab):
    before = tab.frame.true_loop.states[0, -1].copy()
    tab.set(x_ref="0.5, 0, 0", x_max="3")
    assert tab.error is None
    after = tab.frame.true_loop.states[0, -1]
    assert abs(after[0] - 0.5) < 0.05 and abs(before[0]) < 0.05  # the true-model loop now settles at x_ref
    f = fig(tab, "timeseries")
    assert 0.5 in [s.y0 for s in f.layout.shapes if s.line.dash == "dot"]  # the reference drawn
    assert "δ(ε) and the bound sphere assume x_ref = 0" in tab.summary
    assert "x_ref = 0" in fig(tab, "bound").layout.annotations[0].text
    tab.set(x_max="1, 2")
    assert "x_max needs 3 numbers" in tab.error


def test_quantizer_view_changes_with_channel_and_bits(tab):
    q = fig(tab, "quantizer")
    assert q.layout.title.text.startswith("x: angle, b = 4")
    tab.session.views.channel.value = "u: voltage"
    tab.wait()
    q2 = fig(tab, "quantizer")
    assert q2.layout.title.text.startswith("u: voltage, b = 4") and q2 is not q
    tab.set(bits=8)
    q3 = fig(tab, "quantizer")
    assert q3.layout.title.text.startswith("u: voltage, b = 8")
    ratio = float(q3.layout.title.text.split("dithered ")[1].split(" ")[0])
    assert 0.85 < ratio < 1.15  # measured variance / (eps^2/12), no overload with the guard band


def test_pin_overlays_dashed_curves_until_unpinned(tab):
    n_err = len(fig(tab, "error").data)
    tab.session.pin()  # what the "Pin current result" button calls (the browser test presses the button)
    tab.wait()
    assert "Pinned" in tab.session.views.pin_note.content and not tab.session.views.unpin.disabled
    tab.set(dither="none")
    for name in ("error", "cost", "bound"):
        pinned = [tr for tr in fig(tab, name).data if "(pinned" in (tr.name or "")]
        assert pinned and all(tr.line.dash == "dash" for tr in pinned), name
        # measured curves only: no pinned copies of reference lines (slope, Theorem 1) or of marks
        assert not [tr for tr in pinned if tr.mode == "markers" or "Theorem 1" in tr.name or "/bit" in tr.name]
    assert {tr.name for tr in fig(tab, "error").data if "(pinned" in (tr.name or "")} == {
        "LS (pinned b=4)",
        "BCLS (pinned b=4)",
    }
    assert len(fig(tab, "error").data) > n_err
    tab.session.unpin()
    tab.wait()
    assert not [tr for tr in fig(tab, "error").data if "(pinned" in (tr.name or "")]


def test_portraits_at_several_word_lengths(tab):
    p = fig(tab, "portraits")
    assert "b = 2, 4, 6" in p.layout.title.text
    assert {tr.xaxis for tr in p.data} == {"x", "x2", "x3"}
    tab.session.views.compare_bits.value = "3, 9, 40"
    tab.wait()
    p2 = fig(tab, "portraits")
    assert {tr.xaxis for tr in p2.data} == {"x", "x2"} and "ignored: 40" in p2.layout.title.text
    tab.session.views.compare_bits.value = "two"  # nothing usable: the letter's 2, 4, 6 and a note, not a blank
    tab.wait()
    p3 = fig(tab, "portraits")
    assert {tr.xaxis for tr in p3.data} == {"x", "x2", "x3"} and "ignored: two" in p3.layout.title.text


def test_datalength_on_demand_with_progress_cancel_and_cache(dashboard, monkeypatch):
    import app.frames.datalength as bg

    monkeypatch.setattr(bg, "DEFAULT_SAMPLES", (1000, 4000, 16000, 64000))
    monkeypatch.setattr(bg, "MAX_REALIZATIONS", 3)
    tab = open_tab(dashboard)
    try:
        s = tab.session
        assert len(fig(tab, "datalength").data) == 0  # nothing until asked
        s.start_datalength()
        tab.set(bits=5)  # a change cancels it
        s.datalength.thread.join(HANG_S)
        assert "cancelled" in s.views.dl_status.content or "done" in s.views.dl_status.content
        s.start_datalength()
        s.datalength.thread.join(HANG_S)
        assert "done: 4 lengths" in s.views.dl_status.content and s.views.dl_progress.value == 100.0
        tab.wait()
        d = fig(tab, "datalength")
        ls = [tr for tr in d.data if tr.name == "LS mean ± std" and tr.xaxis == "x"][0]
        assert list(ls.x) == [1000, 4000, 16000, 64000] and ls.y[-1] < ls.y[0]  # LS error falls with T
        assert any(tr.name == "Theorem 1 (large T)" for tr in d.data) and "b = 5" in d.layout.title.text
        tab.set(bits=4)
        tab.set(bits=5)  # back at b = 5: the cached study is drawn again, no recomputation
        assert len(fig(tab, "datalength").data) > 0 and not s.datalength.running
    finally:
        tab.close()


def test_bench_dashboard_times_every_view():
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    import bench_dashboard

    from app.frames.cache import SharedCache
    from app.settings.values import Values

    out = bench_dashboard.per_view(
        Values(trajectories=10, steps=60, realizations=4, mpc_steps=15), SharedCache(), [3, 5], None, 1
    )
    assert list(out) == [v.name for v in VIEWS] and all(len(x) == 2 and min(x) >= 0 for x in out.values())
