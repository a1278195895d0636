"""A refused value stays explained until its input is changed again, and the input shows the value in use.

The case (issue 40, 3 of 3 tries): while a computation runs, "ρ auto" is ticked off and ρ = −1 (or 1e308) is
sent. The refusal used to show for 50–300 ms, then the running computation's "ready" cleared it, the browser kept
showing −1 and the results were for the old ρ. The tab here is :class:`benchmarks._wsclient.WsTab`, which sends
exactly what a browser sends and keeps what the server last said of each input.
"""

from __future__ import annotations

import sys
import time

import msgspec
import pytest
from support import HANG_S, ROOT, wait_until

sys.path.insert(0, str(ROOT / "benchmarks"))
from _wsclient import WsTab  # noqa: E402

from app.dashboard.controls import CONTROLS  # noqa: E402
from app.dashboard.inputs import TYPING_PAUSE, blur_clamp  # noqa: E402

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


def test_a_number_typed_key_by_key_is_not_set_back_on_the_way(ws_tab):
    """Typing ρ = 0.005 into its box sends 0 first (refused: ρ > 0), then 0 again for "0." and "0.00", then 0.005.
    The value in use is sent back only once the typing pauses: set back at the first 0, the box would show 1 and
    the next keys would make it 1.005 (what a browser did). A pause at a refused value still sets the box back."""
    tab, s = ws_tab
    c = s.controls
    tab.send("ρ auto", False)
    assert s.wait_idle(HANG_S)
    uuid, seen = tab.wait_for("ρ"), len(tab.sent_back)
    for value in (0, 0.0, 0.0, 0.005):
        tab.send("ρ", value)
        time.sleep(0.2)  # a key every 0.2 s
    wait_until(lambda: s.controls["rho"].value == 0.005, "0.005 taken")
    assert s.wait_idle(HANG_S) and s.last_frame.values.rho == 0.005 and not c.error.visible, c.error.content
    time.sleep(TYPING_PAUSE + 0.5)
    assert [v for _, u, v in tab.sent_back[seen:] if u == uuid] in ([], [0.005])  # 1 never sent back on the way
    t0 = time.monotonic()
    tab.send("ρ", 0)  # ... but left at a refused value, the box is set back after the pause
    wait_until(lambda: tab.value("ρ") == 0.005, "the ρ in use sent back")
    back = next(t for t, u, v in tab.sent_back[seen:] if u == uuid and v == 0.005 and t > t0)
    assert back - t0 >= TYPING_PAUSE and "ρ: the value sent (0)" in c.error.content


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


def test_a_number_box_has_no_bound_for_the_browser_to_clamp_a_refused_value_to(tab):
    """The intermittent browser failure (ρ = −1 typed, the box left before the ρ in use came back): the browser's
    box clamped −1 to its lower bound on leaving it (Mantine's NumberInput) and sent 1e-06, which was taken; the
    refusal went, and the box then showed the ρ sent back. A number box now has no bound in the browser (the
    server checks the range), so it never sends a value of its own; it keeps the decimals the range needs."""
    numbers = [c for c in CONTROLS if c.kind == "number"]
    assert any(c.name == "rho" for c in numbers)
    for c in numbers:
        h = tab.controls[c.name]
        assert h.min is None and h.max is None and blur_clamp(h, -1e300) is None, c.name
    assert tab.controls["rho"].precision >= 6  # 1e-06 can still be typed


@pytest.mark.parametrize(("label", "name", "bad"), [("word length b", "bits", 400), ("steps", "steps", -5)])
def test_a_slider_box_bound_sent_on_leaving_a_refused_value_is_shown_with_its_results(ws_tab, label, name, bad):
    """A slider's box keeps its bounds (the slider needs them): a value out of them is refused, and if the box is
    left before the value in use arrives, the browser sends the box's bound (Mantine clamps on blur) and then shows
    the value in use sent back. The bound is taken, and sent back too: the box shows the value the results are
    for (it used to show the value sent back after the refusal, next to results for the bound)."""
    tab, s = ws_tab
    c = s.controls
    before, bound = c[name].value, blur_clamp(c[name], bad)
    assert bound is not None and bound != before  # (the browser's box would send this on leaving it)
    tab.send(label, bad)
    wait_until(lambda: tab.value(label) == before, "the value in use sent back")
    # the bound, sent by the box as it was left before the value in use arrived (which the box then showed)
    message = {"type": "GuiUpdateMessage", "uuid": tab.uuids[label], "updates": {"value": bound}}
    tab.ws.send(msgspec.msgpack.encode(message))
    assert s.wait_idle(HANG_S)
    wait_until(lambda: c[name].value == bound and not c.error.visible, "the bound taken, the refusal gone")
    wait_until(lambda: tab.value(label) == bound, "the box shows the value in use")
    assert s.wait_idle(HANG_S) and getattr(s.last_frame.values, name) == bound
