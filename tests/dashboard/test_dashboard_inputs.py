"""Every value that reaches the server over the websocket is checked before anything is computed.

A browser offers only what the panel allows; these tests send what a hand-made
client could (out-of-range sliders, huge numbers, absurd texts) exactly as the
browser would (a ``GuiUpdateMessage`` over the tab's own websocket), and check
that the tab explains it in plain words and keeps its last good view.
"""

from __future__ import annotations

import msgspec
import pytest
from support import HANG_S, wait_until

from app.dashboard.controls import CONTROLS
from app.dashboard.inputs import MAX_TEXT, check_value
from app.settings.values import InputError


def send(tab, handle, value, timeout: float = HANG_S):
    """Send ``value`` for ``handle`` over the tab's websocket, as a browser does; wait until handled."""
    g0 = tab.session.generation
    tab.ws.send(
        msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": handle._impl.uuid, "updates": {"value": value}})
    )
    wait_until(lambda: tab.session.generation > g0, "the server took the value", timeout, every=0.01)
    return tab.wait()


def send_refused(tab, handle, value) -> str:
    """Send ``value`` for ``handle``; it is refused as it arrives (before viser converts it): return the message."""
    before, gen = handle.value, tab.session.generation
    tab.controls.error.visible = False
    _send_raw(tab, handle, {"value": value})
    wait_until(lambda: tab.error is not None, f"{handle.label} = {value!r} refused")
    assert handle.value == before and tab.session.generation == gen  # the input keeps its value, nothing runs
    return tab.error


BAD = [
    ("q0", 400.0, "outside the slider's range -3 … 3"),  # was OverflowError in 10**400
    ("q0", 1e308, "outside the slider's range"),
    ("bits", 400, "word length b: the value sent (400) was refused (400 is outside the slider's range 1 … 16)"),
    ("bits", 1e308, "word length b: the value sent (1e+308) was refused (1e+308 is outside"),
    ("trajectories", 5000, "trajectories: the value sent (5000) was refused (5000 is outside"),
    ("steps", -5, "outside"),
    ("horizon", 200, "horizon: the value sent (200) was refused (200 is outside"),
    ("mpc_steps", 10000, "outside"),
    ("u_max", 1e308, "input bound"),
    ("data_seed", 1e308, "data seed"),
    ("rho", 1e300, "ρ"),
    ("theta", 5.0, "θ"),
]


@pytest.mark.slow
def test_out_of_range_values_are_explained_and_the_view_stays(tab):
    for name, value, words in BAD:
        view, frames = tab.session.portrait.view, tab.session.frames_drawn
        handle = tab.controls.q_sliders[0] if name == "q0" else tab.controls[name]
        error = send_refused(tab, handle, value)
        assert words in error and "the value sent" in error, (name, value, error)
        assert "internal error" not in error
        assert tab.session.portrait.view is view and tab.session.frames_drawn == frames  # the last good view stays
        assert not tab.controls.status.content.startswith("ready")
        c = None if name == "q0" else CONTROLS[[c.name for c in CONTROLS].index(name)]
        good, step = (0.0, 0.1) if c is None else (c.lo, c.step)
        good = good if good != handle.value else good + step  # a change (the refused value never was one)
        send(tab, handle, int(good) if isinstance(handle.value, int) else good)
        assert tab.error is None and tab.controls.status.content.startswith("ready"), (name, tab.error)


def test_deeply_nested_brackets_are_refused_in_plain_words(tab):
    tab.set(system="custom")
    error = send_refused(tab, tab.controls["a_text"], "[" * 5000 + "1" + "]" * 5000)  # was RecursionError
    assert "too many nested brackets" in error and "A: the value sent" in error and "internal error" not in error
    assert "too long" in send_refused(tab, tab.controls["a_text"], "1" * (MAX_TEXT + 1))


def test_absurd_fixed_ranges_are_refused(tab):
    tab.set(range_mode="fixed")
    view = tab.session.portrait.view
    for text, words in [
        ("0, 5e-324", "narrow"),  # was: every realization fails, then a reshape error
        ("-1e308, 1e308", "between -1e+12"),  # was: 'ready' with eps = inf and 20/20 failures
        ("nan, 1", "finite"),
    ]:
        send(tab, tab.controls["fixed_range"], text)
        assert tab.error is not None and words in tab.error, tab.error
        assert tab.session.portrait.view is view


def test_all_failed_identifications_or_infinite_eps_are_never_shown_as_ready():
    from types import SimpleNamespace as NS

    import numpy as np

    from app.dashboard.inputs import unusable as _unusable

    ok = NS(eps=np.array([0.1, 0.2]), failed=np.array([False, True]), notes=[])
    bad = NS(eps=np.array([0.1, 0.2]), failed=np.array([True, True]), notes=["identification failed: singular"])
    inf = NS(eps=np.array([np.inf, 0.2]), failed=np.array([False, False]), notes=[])
    frame = lambda **idents: NS(stage="current", bits=5, idents=idents)  # noqa: E731
    assert _unusable(frame(LS=ok, BCLS=bad)) is None  # one estimator still has models: a result
    msg = _unusable(frame(LS=bad, BCLS=bad))
    assert "every identification failed at b = 5 (all 2 dither realizations): identification failed: singular" == msg
    assert "not a finite number" in _unusable(frame(LS=inf))


@pytest.mark.parametrize("value", [float("nan"), float("inf"), "3", None, True, [1]])
def test_check_value_refuses_what_is_not_a_number(value):
    bits = next(c for c in CONTROLS if c.name == "bits")
    with pytest.raises(InputError, match="word length b"):
        check_value(bits, value)


def test_dropdown_and_checkbox_values_must_be_offered():
    dither = next(c for c in CONTROLS if c.name == "dither")
    with pytest.raises(InputError, match="is not one of"):
        check_value(dither, "telepathy")
    guard = next(c for c in CONTROLS if c.name == "guard")
    with pytest.raises(InputError, match="on/off"):
        check_value(guard, 1)


def _send_raw(tab, handle, updates: dict) -> None:
    tab.ws.send(msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": handle._impl.uuid, "updates": updates}))


@pytest.mark.parametrize(
    "updates, words",
    [
        ({"value": "abc"}, "expected a whole number, got str"),  # refused before viser converts it
        ({"value": [1, 2]}, "expected a whole number, got list"),
        ({"no_such_prop": 1}, "AssertionError"),  # a property the input does not have
    ],
)
def test_values_viser_itself_refuses_are_explained_not_dropped(tab, updates, words):
    """These never reach our callbacks (refused before viser converts them, or by viser): the tab says so, the view
    and the value stay."""
    handle, before = tab.controls["bits"], tab.controls["bits"].value
    gen, frames = tab.session.generation, tab.session.frames_drawn
    _send_raw(tab, handle, updates)
    wait_until(lambda: tab.error is not None, "an error shown")
    assert "word length b: the value sent" in tab.error and "was refused" in tab.error and words in tab.error
    assert "keeps its last value" in tab.error
    assert handle.value == before and tab.session.generation == gen and tab.session.frames_drawn == frames
    send(tab, handle, 7)  # a good value clears it
    assert tab.error is None and tab.frame.bits == 7


def test_a_share_url_request_from_a_client_opens_no_public_tunnel(tab):
    """viser would open a tunnel through its public relay for any client asking (the button is hidden)."""
    tab.ws.send(msgspec.msgpack.encode({"type": "ShareUrlRequest"}))
    send(tab, tab.controls["bits"], 6)  # handled after the request (one connection, messages in order)
    assert tab.app.server._share_tunnel is None
