"""Follow links (a tab shown live and read-only in other tabs) and the page redirects that put a view code in the
address, in-process: tabs are websocket clients of a server in this process (``tests/support.py``), a change
"made in the browser" is a ``GuiUpdateMessage`` over the tab's websocket, as viser's client sends it. The same
with two real browsers: ``tests/system/test_dashboard_follow_browser.py``.
"""

from __future__ import annotations

import http.client
import urllib.request

import msgspec
import pytest
from support import SMALL, Tab, open_tab, wait_until

from app.dashboard.follow import EXPLORE
from app.figures import registry
from app.settings.viewcodes import page_location, parse_path


def _send(tab: Tab, handle, value) -> None:
    """What viser's client sends when the person changes input ``handle`` (a disabled input sends nothing)."""
    tab.ws.send(
        msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": handle._impl.uuid, "updates": {"value": value}})
    )


def _follow(dashboard, code: str, spare: str | None = "abcdef") -> Tab:
    """A tab opened at ``code``'s follow link (the address the server redirects it to names ``spare``)."""
    return Tab(dashboard, f"/f/{code}" + (f"/{spare}" if spare else ""))


def _mirrored(leader: Tab, follower: Tab) -> bool:
    """The follower shows what the leader drew last (its settings and its last frame)."""
    f, lf = follower.session, leader.session.last_frame
    return f.last_frame is lf and f.ui.panel_values() == leader.session.ui.panel_values()


def _wait_mirrored(leader: Tab, *followers: Tab) -> None:
    leader.wait()
    for f in followers:
        wait_until(lambda f=f: _mirrored(leader, f), "the follower shows the leader's newest view")
        f.wait()


# ----- the addresses: which page requests are redirected where ------------------------------------------------------
def test_page_requests_are_redirected_to_an_address_holding_a_code_and_a_spare():
    codes = iter(["newnew", "sparea", "spareb", "sparec", "spared", "sparee"])
    fresh = lambda: next(codes)  # noqa: E731
    assert page_location("/", "h:1", False, fresh) == "/?websocket=ws://h:1/n/newnew/sparea"
    assert page_location("/f/KQBXTR", "h:1", True, fresh) == "/?websocket=wss://h:1/f/kqbxtr/spareb"
    assert page_location("/v/kqbxtr/", "h:1", False, fresh) == "/?websocket=ws://h:1/v/kqbxtr/sparec"
    long = "/?websocket=ws://10.0.0.5:8080/v/kqbxtr&darkMode"  # a long link (bookmarks, older links) gets a spare
    assert page_location(long, "h:1", False, fresh) == "/?websocket=ws://10.0.0.5:8080/v/kqbxtr/spared&darkMode="
    for served in ("/?websocket=ws://h:1/v/kqbxtr/abcdef", "/index.html", "/favicon.ico", "/x/kqbxtr"):
        assert page_location(served, "h:1", False, fresh) is None, served
    assert page_location("/", 'evil"<x>', False, fresh) is None  # a Host header never written back as it came
    assert parse_path("/f/kqbxtr/spared") == ("f", "kqbxtr", "spared") and parse_path("/") is None


def test_the_bare_address_gets_a_code_in_its_address_and_a_reload_comes_back_to_it(dashboard):
    assert dashboard.redirecting  # the hook is in place with this viser (else: long links, see the panel's line)
    url = urllib.request.urlopen(dashboard.url, timeout=60).url  # (follows the redirect, as a browser does)
    path = url.split("?websocket=", 1)[1].split(str(dashboard.port), 1)[1]
    kind, code, spare = parse_path(path)
    assert kind == "n" and spare is not None
    t = Tab(dashboard, path).set(bits=9, **SMALL)
    try:
        assert t.session.codes.view.code == code and t.session.codes.view.kept
        assert not t.session.codes.status.visible  # a code the server handed out: no "not known" line
        assert "A reload or the link brings these settings back" in t.session.codes.hint.content
    finally:
        t.close()
    wait_until(lambda: not dashboard.sessions, "the closed tab is gone")
    again = Tab(dashboard, path).wait()  # the reload: the same address
    try:
        assert again.session.codes.view.code == code and again.frame.values.bits == 9
    finally:
        again.close()


def test_a_websocket_at_the_bare_address_still_connects_and_says_how_to_come_back(tab):
    conn = http.client.HTTPConnection("127.0.0.1", tab.app.port, timeout=60)
    conn.request("GET", "/")
    assert conn.getresponse().status == 302  # a page request is redirected; the test's websocket was not
    assert not tab.session.codes.view.kept
    assert "does not hold its code: the link" in tab.session.codes.hint.content


# ----- following --------------------------------------------------------------------------------------------------
def test_a_follower_shows_the_leaders_settings_and_pictures_without_computing(dashboard, tab):
    code = tab.session.codes.view.code
    f = _follow(dashboard, code)
    try:
        _wait_mirrored(tab, f)
        assert f.session.codes.view.follow == code and "Following view" in f.session.follower.banner.content
        assert f"following view **{code}**" in f.session.codes.line.content
        assert "1 following" in tab.session.codes.hint.content
        tab.set(bits=3)
        _wait_mirrored(tab, f)
        tab.set(lesson="dither")
        _wait_mirrored(tab, f)
        assert f.frame.values.lesson == "dither" and f.frame.values.bits == tab.frame.values.bits
        assert f.session.views.shown == tab.session.views.shown  # the lesson's key view, as the teacher's
        assert f.session.controls.lesson_text.content == tab.session.controls.lesson_text.content
        assert f.summary == tab.summary and "ready" in f.session.controls.status.content
        linear = {v.name for v in registry.VIEWS}  # (the nonlinear views stay blank on a linear plant's tab)
        for name, plot in ((n, p) for n, p in tab.session.plots.items() if n in linear):  # the leader's very JSON
            assert f.session.plots[name]._plotly_json_str is plot._plotly_json_str, name
        assert f.session.timings == {} and f.session.ui.renderer.figures == {}  # never computed, never rendered
        assert dashboard.views.get("abcdef") is None  # a follower keeps no settings of its own
    finally:
        f.close()
    wait_until(lambda: "following" not in tab.session.codes.hint.content, "the leader's count drops")


def test_a_followers_inputs_change_nothing_and_say_why(dashboard, tab):
    tab.set(bits=7)
    f = _follow(dashboard, tab.session.codes.view.code)
    try:
        _wait_mirrored(tab, f)
        c = f.session.controls
        assert c["bits"].disabled and c["lesson"].disabled and c.play.disabled and f.session.codes.box.disabled
        assert all(s.disabled for s in c.q_sliders + c.r_sliders)
        assert not f.session.views.group.disabled and not f.session.follower.button.disabled
        _send(f, c["bits"], 2)  # a value sent anyway (a disabled input sends none): refused, with one line
        wait_until(lambda: c.error.visible, "the refusal is shown")
        assert "follows view" in c.error.content and "explore from here" in c.error.content
        f.wait()
        assert c["bits"].value == 7 and tab.wait().frame.values.bits == 7
        assert dashboard.views.get(tab.session.codes.view.code).bits == 7
        _send(f, f.session.views.group, "Control")  # what this screen shows is the follower's own choice
        wait_until(lambda: f.session.views.shown == "Control", "the follower's plots panel shows another group")
        assert tab.session.views.shown != "Control"
        tab.set(bits=5)  # the teacher moves on: the follower follows, the refusal line goes
        _wait_mirrored(tab, f)
        assert not c.error.visible
    finally:
        f.close()


def test_explore_from_here_makes_the_follower_a_view_of_its_own(dashboard, tab):
    tab.set(bits=6)
    code = tab.session.codes.view.code
    f = _follow(dashboard, code, "abcdef")
    try:
        _wait_mirrored(tab, f)
        assert f.session.follower.button.label == EXPLORE
        _send(f, f.session.follower.button, True)  # the click
        wait_until(lambda: not f.session.follower.active, "the follower explored")
        f.wait()
        view = f.session.codes.view
        assert view.code == "abcdef" and view.follow is None and view.kept  # the spare its address names
        assert "your own view abcdef" in f.session.follower.banner.content and not f.session.follower.button.visible
        assert not f.session.controls["bits"].disabled and f.frame.values.bits == 6
        assert "0 following" not in tab.session.codes.hint.content and "following" not in tab.session.codes.hint.content
        f.set(bits=12)  # the student's changes stay with the student ...
        assert tab.wait().frame.values.bits == 6 and dashboard.views.get(code).bits == 6
        assert dashboard.views.get("abcdef").bits == 12
        tab.set(bits=2)  # ... and the teacher's no longer reach the student
        assert f.wait().frame.values.bits == 12
    finally:
        f.close()
    wait_until(lambda: len(dashboard.sessions) == 1, "the explored tab closed")
    again = _follow(dashboard, code, "abcdef").wait()  # its reload: the same address, now its own view
    try:
        assert again.session.follower is None and again.session.codes.view.code == "abcdef"
        assert again.frame.values.bits == 12
    finally:
        again.close()


def test_followers_keep_the_last_view_when_the_leader_leaves_and_follow_its_reload(dashboard):
    lead = open_tab(dashboard).set(bits=8)
    code = lead.session.codes.view.code
    f = _follow(dashboard, code)
    try:
        _wait_mirrored(lead, f)
        lead.close()
        wait_until(lambda: f.session.follower.state == "left", "the follower says the leader left")
        assert "has closed" in f.session.follower.banner.content and f.frame.values.bits == 8
        back = Tab(dashboard, f"/v/{code}").wait()  # the teacher's reload: the same code, a new tab
        try:
            assert back.session.codes.view.code == code
            back.set(bits=11)
            _wait_mirrored(back, f)
            assert f.session.follower.state == "open" and f.frame.values.bits == 11
        finally:
            back.close()
    finally:
        f.close()


def test_a_follow_link_of_a_view_whose_tab_is_closed_shows_its_saved_settings_until_it_opens(dashboard):
    dashboard.views.put("kqbxtr", dashboard.defaults.replace(bits=10, **SMALL, mpc_steps=15))
    f = _follow(dashboard, "kqbxtr").wait()
    try:
        assert f.session.follower.state == "waiting" and f.frame.values.bits == 10  # computed here, read-only
        assert f.session.controls["bits"].disabled
        lead = Tab(dashboard, "/v/kqbxtr").wait()
        try:
            lead.set(bits=4)
            _wait_mirrored(lead, f)
            assert f.session.follower.state == "open"
        finally:
            lead.close()
    finally:
        f.close()


@pytest.mark.parametrize("path", ["/f/zzzzzz/abcdef", "/f/kqb/abcdef"])
def test_a_follow_link_of_an_unknown_code_is_one_line_and_the_default_view(dashboard, path):
    t = Tab(dashboard, path).wait()
    try:
        st = t.session.codes.status
        assert st.visible and "\n" not in st.content
        assert ("not known on this server" in st.content) if "zzzzzz" in path else ("is not a code" in st.content)
        assert t.session.follower is None and t.session.codes.view.code == "abcdef"  # a view of its own
        assert not t.session.controls["bits"].disabled
        assert t.frame.values.bits == dashboard.defaults.bits
    finally:
        t.close()


def test_many_followers_each_push_once_per_leader_draw_and_never_compute(dashboard, tab):
    code = tab.session.codes.view.code
    followers = [_follow(dashboard, code, None) for _ in range(5)]
    try:
        _wait_mirrored(tab, *followers)
        pushed = [f.session.frames_drawn for f in followers]
        drawn = tab.session.frames_drawn
        for b in (3, 9, 5):
            tab.set(bits=b)
        _wait_mirrored(tab, *followers)
        new = tab.session.frames_drawn - drawn
        for f, before in zip(followers, pushed):
            assert 1 <= f.session.frames_drawn - before <= new  # at most one push per leader draw (no loop)
            assert f.session.timings == {}
        assert f"{len(followers)} following" in tab.session.codes.hint.content
        assert dashboard.follow.followers(code) == len(followers)
    finally:
        for f in followers:
            f.close()
    wait_until(lambda: dashboard.follow.followers(code) == 0, "the followers left")
