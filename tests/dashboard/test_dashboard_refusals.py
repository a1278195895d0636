"""A refused value stays explained until its input is changed again, and the input shows the value in use.

The case (issue 40, 3 of 3 tries): while a computation runs, "ρ auto" is ticked off and ρ = −1 (or 1e308) is
sent. The refusal used to show for 50–300 ms, then the running computation's "ready" cleared it, the browser kept
showing −1 and the results were for the old ρ. The tab here is :class:`benchmarks._wsclient.WsTab`, which sends
exactly what a browser sends and keeps what the server last said of each input.
"""

from __future__ import annotations

import sys

import pytest
from support import HANG_S, ROOT, wait_until

sys.path.insert(0, str(ROOT / "benchmarks"))
from _wsclient import WsTab  # noqa: E402

#: Settings that keep the in-process computation busy for a while (so ρ arrives while it runs).
BUSY = {"trajectories": 400, "steps": 1000, "realizations": 20}


@pytest.fixture
def ws_tab(dashboard):
    t = WsTab(dashboard.url, HANG_S)
    try:
        (session,) = dashboard.wait_for_sessions(1, HANG_S)
        t.wait_ready(HANG_S)
        yield t, session
    finally:
        t.close()


@pytest.mark.slow  # a computation at a few hundred trajectories, in-process
@pytest.mark.parametrize("bad", [-1.0, 1e308])
def test_a_rho_refused_while_computing_stays_shown_and_the_input_shows_the_rho_in_use(ws_tab, bad):
    tab, s = ws_tab
    for label, value in BUSY.items():
        tab.send(label, value)
    wait_until(lambda: s.controls.status.content.startswith(("computing", "queued")), "the computation runs")
    tab.send("ρ auto", False)
    tab.send("ρ", bad)
    wait_until(lambda: tab.value("ρ") == 1.0, "the browser's ρ set back to the value in use")
    assert s.controls["rho"].value == 1.0 and s.controls["rho_auto"].value is False
    assert s.wait_idle(HANG_S)  # the running computation finished ("ready") ...
    c = s.controls
    assert c.status.content.startswith("ready"), c.status.content
    assert c.error.visible and "ρ: the value sent" in c.error.content, c.error.content  # ... and the refusal stays
    assert s.last_frame.values.rho_auto is False and s.last_frame.values.rho == 1.0  # results for the ρ shown
    tab.send("θ", 0.6)  # another input changed: the refusal still stays (it is about ρ)
    assert s.wait_idle(HANG_S) and c.error.visible and "ρ: the value sent" in c.error.content
    tab.send("ρ", 2.0)  # ρ changed again: its refusal goes
    wait_until(lambda: not c.error.visible, "the refusal goes once ρ is changed")
    assert s.wait_idle(HANG_S) and s.last_frame.values.rho == 2.0 and not c.error.visible


def test_refusals_of_two_inputs_each_stay_until_that_input_changes(ws_tab):
    tab, s = ws_tab
    c = s.controls
    tab.send("ρ auto", False)
    assert s.wait_idle(HANG_S)
    tab.send("ρ", -1.0)
    tab.send("word length b", 400)
    wait_until(lambda: tab.value("word length b") == c["bits"].value, "b set back")
    wait_until(
        lambda: "word length b: the value sent" in c.error.content and "ρ: the value sent" in c.error.content,
        "both refusals shown",
    )
    tab.send("word length b", 5)  # b taken: its line goes, ρ's stays
    wait_until(lambda: "word length b: the value sent" not in c.error.content, "b's refusal goes")
    assert s.wait_idle(HANG_S) and c.error.visible and "ρ: the value sent" in c.error.content
    assert s.last_frame.values.bits == 5


@pytest.mark.parametrize(("label", "name", "bad"), [("ρ", "rho", -1.0), ("word length b", "bits", 400)])
def test_the_box_bound_sent_on_leaving_a_refused_value_keeps_the_refusal(ws_tab, label, name, bad):
    """The order of the intermittent browser failure: a value out of the box's bounds is refused, and the box is
    left before the value in use arrives, so the browser sends its bound (Mantine clamps on blur). The bound is the
    refused value again: the refusal stays and the input keeps, and the box shows, the value in use."""
    from app.dashboard.inputs import blur_clamp

    tab, s = ws_tab
    c = s.controls
    tab.send("ρ auto", False)
    assert s.wait_idle(HANG_S)
    before = c[name].value
    bound = blur_clamp(c[name], bad)
    assert bound is not None and bound != before  # (the browser's box would send this on leaving it)
    tab.send(label, bad)
    tab.send(label, bound)  # at once: on the wire before the value in use can reach the browser
    wait_until(lambda: f"{label}: the value sent" in c.error.content, "the refusal shown")
    assert s.wait_idle(HANG_S)
    assert c[name].value == before and c.error.visible and f"{label}: the value sent" in c.error.content
    wait_until(lambda: tab.value(label) == before, "the box set back to the value in use")
    assert getattr(s.last_frame.values, name) == before
    tab.send(label, bound)  # the bound typed afterwards is a choice: taken, the refusal goes
    wait_until(lambda: not c.error.visible, "the refusal goes once the input is changed")
    assert s.wait_idle(HANG_S) and getattr(s.last_frame.values, name) == bound
