"""Presenter mode, auto-play over b, and view codes (links that survive a reload), without a browser.

Tabs here are websocket clients of an in-process server (``tests/support.py``); a change "made in the browser"
is a ``GuiUpdateMessage`` over the tab's websocket, exactly as viser's client sends it. The browser walkthrough
(fonts, widths, reload) is ``tests/system/test_dashboard_teach_browser.py``.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time

import msgspec
import pytest
from support import HANG_S, ROOT, SMALL, Tab, wait_until

from app.dashboard.presenter import LEFT_SHARE, LEFT_WIDTH, SCENE_ASPECT, SHOW_PLOT, SHOW_SCENE, WIDE, PresenterLayout
from app.figures.presenter import PLOT_FONT, presenter_figure
from app.figures.registry import KOOPMAN_VIEWS
from app.settings.values import InputError, Values
from app.settings.viewcodes import CODE_LETTERS, ViewStore, code_from_path, normalize_code, open_view, view_link

# slow: each test starts a dashboard and waits for drawn frames (auto-play steps b once a second)
pytestmark = pytest.mark.slow


# ----- view codes: the store and the parsing ---------------------------------------------------------------------
def test_codes_parse_from_typed_text_links_and_websocket_paths():
    assert normalize_code(" KQbxtr ") == "kqbxtr"
    assert normalize_code(view_link("10.0.0.5:8080", "kqbxtr")) == "kqbxtr"
    assert code_from_path("/v/kqbxtr") == "kqbxtr" and code_from_path("/") is None
    assert code_from_path("/v/kqb") is None and code_from_path("/x/kqbxtr") is None
    for bad in ("", "abc", "abcdefg", "abc12d", "abcdel"):  # 'l' is left out (read as 1 off a projector)
        if not bad:
            continue
        with pytest.raises(InputError, match="is not a code: a code is 6 letters") as exc:
            normalize_code(bad)
        assert "\n" not in str(exc.value)
    assert set(ViewStore().new_code()) <= set(CODE_LETTERS)


def test_the_store_keeps_the_newest_settings_bounded_and_in_its_file(tmp_path):
    path = tmp_path / "cache" / "views.json"
    store = ViewStore(path, max_views=3)
    for i, code in enumerate(["aaaaaa", "bbbbbb", "cccccc"]):
        store.put(code, Values(bits=i + 2))
    assert store.get("aaaaaa").bits == 2  # used: now the newest
    store.put("dddddd", Values(bits=9, presenter=True))
    assert len(store) == 3 and "bbbbbb" not in store  # the least recently used was dropped
    store.flush()
    doc = json.loads(path.read_text())
    assert doc["kind"] == "qsid-view-codes" and set(doc["views"]) == {"aaaaaa", "cccccc", "dddddd"}
    again = ViewStore(path, max_views=3)  # a restarted server reads them back
    assert again.get("dddddd") == Values(bits=9, presenter=True) and again.load_note is None


def test_the_store_writes_equal_settings_as_json_once_for_every_code():
    store = ViewStore()
    for code in ("aaaaaa", "bbbbbb", "aaaaaa"):  # a class's tabs, each after every frame, on the same settings
        store.put(code, Values(bits=7))
    store.put("aaaaaa", Values(bits=8))
    info = store._json.cache_info()
    assert (info.misses, info.hits) == (2, 2)
    assert store.get("aaaaaa") == Values(bits=8) and store.get("bbbbbb") == Values(bits=7)


def test_a_broken_store_file_is_one_note_and_an_empty_store(tmp_path):
    path = tmp_path / "views.json"
    path.write_text("{not json")
    store = ViewStore(path)
    assert len(store) == 0 and "not read" in store.load_note
    path.write_text(json.dumps({"kind": "qsid-view-codes", "views": {"aaaaaa": "{}", "zz": "x"}}))
    assert len(ViewStore(path)) == 0  # entries the dashboard would refuse are dropped, one by one


def test_open_view_says_why_a_link_gave_defaults():
    store = ViewStore()
    store.put("kqbxtr", Values(bits=11))
    v, view = open_view(store, "/v/kqbxtr", "h:1", Values())
    assert v.bits == 11 and view.code == "kqbxtr" and view.kept and view.note == ""
    v, view = open_view(store, "/v/zzzzzz", "h:1", Values(bits=5))
    assert v.bits == 5 and view.code == "zzzzzz" and "is not known on this server" in view.note
    v, view = open_view(store, "/n/zzzzzz/abcdef", "h:1", Values(bits=5))  # a code the server handed out
    assert v.bits == 5 and view.code == "zzzzzz" and view.kept and view.note == ""
    v, view = open_view(store, "/v/12", "h:1", Values())
    assert not view.kept and "'12' is not a code" in view.note and view.code != "12"
    v, view = open_view(store, "/x/kqbxtr", "h:1", Values())
    assert not view.kept and "holds no view code" in view.note
    v, view = open_view(store, "/", "h:1", Values())
    assert not view.kept and view.note == ""


def test_a_link_whose_tab_is_open_gets_a_code_of_its_own():
    """A class opening the teacher's link while the teacher's tab is open: the settings, never the code (so a
    student's change cannot reach the teacher's view); a reload (no tab holds the code) keeps it."""
    store = ViewStore()
    store.put("kqbxtr", Values(bits=11))
    v, view = open_view(store, "/v/kqbxtr", "h:1", Values(), in_use=lambda code: code == "kqbxtr")
    assert v.bits == 11 and view.code != "kqbxtr" and not view.kept and "kqbxtr" in view.note
    assert store.get(view.code) is None  # nothing stored under the new code until the tab draws
    v, view = open_view(store, "/v/kqbxtr", "h:1", Values(), in_use=lambda code: False)
    assert v.bits == 11 and view.code == "kqbxtr" and view.kept
    # the address names a spare code: the tab takes it (so its reload comes back to it) ...
    v, view = open_view(store, "/v/kqbxtr/abcdef", "h:1", Values(), in_use=lambda code: code == "kqbxtr")
    assert v.bits == 11 and view.code == "abcdef" and view.kept
    store.put("abcdef", Values(bits=3))  # ... which then keeps that tab's own settings
    v, view = open_view(store, "/v/kqbxtr/abcdef", "h:1", Values(), in_use=lambda code: code == "kqbxtr")
    assert v.bits == 3 and view.code == "abcdef" and view.kept and view.note == ""


# ----- view codes in a live tab -------------------------------------------------------------------------------------
def test_a_link_opens_the_settings_its_tab_had_last(dashboard, tab):
    tab.set(bits=9, dither="tpdf")
    code = tab.session.codes.view.code
    assert dashboard.views.get(code).bits == 9
    assert f"view code **{code}**" in tab.session.codes.line.content
    assert view_link(f"127.0.0.1:{dashboard.port}", code, short=True) in tab.session.codes.line.content
    tab.close()  # a reload: the same link opens a new connection at /v/CODE
    wait_until(lambda: tab.session.client.client_id not in dashboard.sessions, "the closed tab is gone")
    again = Tab(dashboard, f"/v/{code}").wait()
    try:
        assert again.session.codes.view.code == code and again.session.codes.view.kept
        assert again.frame.values.bits == 9 and again.frame.values.dither == "tpdf"
        assert again.frame.values.trajectories == SMALL["trajectories"]
        assert not again.session.codes.status.visible
    finally:
        again.close()


def test_an_unknown_code_in_a_link_is_one_line_in_the_panel(dashboard):
    t = Tab(dashboard, "/v/qqqqqq").wait()
    try:
        st = t.session.codes.status
        assert st.visible and "**qqqqqq** is not known on this server" in st.content and "\n" not in st.content
        t.set(bits=7)
        assert dashboard.views.get("qqqqqq").bits == 7  # the link works from now on
    finally:
        t.close()


@pytest.mark.parametrize(
    "typed,expect",
    [("12ab", "is not a code: a code is 6 letters"), ("zzzzzz", "**zzzzzz** is not known on this server")],
)
def test_a_bad_code_typed_is_one_clear_line(tab, typed, expect):
    bits = tab.frame.values.bits
    tab.session.codes.box.value = typed
    st = tab.session.codes.status
    wait_until(lambda: st.visible, "the status line shows")
    assert expect in st.content and "\n" not in st.content
    assert tab.wait().frame.values.bits == bits  # nothing else changed


def test_a_code_typed_by_a_student_applies_that_view(dashboard, tab):
    tab.set(bits=12, identification="LS")
    code = tab.session.codes.view.code
    other = Tab(dashboard).set(mpc_steps=15, **SMALL)
    try:
        assert other.session.codes.view.code != code and other.frame.values.bits != 12
        other.session.codes.box.value = code.upper()
        wait_until(lambda: other.session.codes.status.visible, "the status line shows")
        wait_until(lambda: other.wait().frame.values.bits == 12, "the view's settings applied")
        assert other.frame.values.identification == "LS"
        assert f"Loaded view **{code}**" in other.session.codes.status.content
    finally:
        other.close()


def test_the_same_code_typed_twice_loads_twice(dashboard, tab):
    tab.set(bits=12)
    code = tab.session.codes.view.code
    other = Tab(dashboard).set(**SMALL)
    try:
        for _ in range(2):  # between the two: the student moves b away again
            other.set(bits=3)
            other.session.codes.box.value = code
            wait_until(lambda: other.wait().frame.values.bits == 12, "the view's settings applied")
            wait_until(lambda: other.session.codes.box.value == "", "the box emptied for the next code")
    finally:
        other.close()


def test_a_code_typed_the_first_time_restores_its_view_not_its_lessons_defaults(dashboard, tab):
    """Walkthrough repro: the view (lesson bound, b = 13, data seed 5) typed once came up as the lesson's defaults
    (b = 8, seed 1): the lesson named in the code was opened anew over the settings just loaded."""
    tab.set(lesson="bound")
    tab.set(bits=13, data_seed=5)
    code = tab.session.codes.view.code
    other = Tab(dashboard).set(**SMALL)
    try:
        assert other.frame.values.lesson == "(none)"
        other.session.codes.box.value = code  # typed once
        wait_until(lambda: other.wait().frame.values.lesson == "bound", "the view's settings applied")
        v = other.wait().frame.values
        assert (v.bits, v.data_seed, v.system) == (13, 5, "dc-motor")
        text = other.controls.lesson_text
        assert text.visible and "The ultimate bound" in text.content
        assert "✎ **Modified from the lesson** (data seed)" in text.content  # the seed its numbers depend on
        assert other.session.views.shown == "Control"  # the lesson's key view, as in the teacher's tab
    finally:
        other.close()


def test_a_student_on_the_teachers_link_cannot_change_the_teachers_view(dashboard, tab):
    tab.set(bits=10)
    code = tab.session.codes.view.code
    student = Tab(dashboard, f"/v/{code}").wait()
    try:
        assert student.frame.values.bits == 10  # the teacher's settings ...
        assert student.session.codes.view.code != code  # ... under a code of the student's own
        student.set(bits=2)
        assert dashboard.views.get(code).bits == 10 and tab.wait().frame.values.bits == 10
        assert dashboard.views.get(student.session.codes.view.code).bits == 2
    finally:
        student.close()


def test_a_lesson_modified_says_so_and_one_click_brings_it_back(tab):
    tab.set(lesson="dither")
    text = tab.controls.lesson_text
    assert not tab.session.mark.back.visible and "Modified" not in text.content
    tab.set(bits=12)  # moving b is the lesson itself: no mark
    assert not tab.session.mark.back.visible
    tab.set(dither="none", fixed_range="-40,40")  # what its text says to do next: following it, no mark either
    assert not tab.session.mark.back.visible and "Modified" not in text.content
    tab.set(dither="tpdf")  # not what the text says
    assert tab.session.mark.back.visible and "✎ **Modified from the lesson** (dither)" in text.content
    tab.set(dither="none", data_seed=7)  # a seed: every number the text quotes depends on it
    assert tab.session.mark.back.visible and "✎ **Modified from the lesson** (data seed)" in text.content
    assert "Why dither" in text.content  # the lesson's text stays, marked
    tab.session.mark.press()  # the button's callback
    tab.wait()
    v = tab.frame.values
    assert (v.dither, v.data_seed, v.fixed_range, v.lesson) == ("subtractive", 0, "-20, 20", "dither")
    assert not tab.session.mark.back.visible and "Modified" not in text.content


def test_a_lesson_that_picks_the_quantizer_channel_is_not_marked_modified(tab):
    tab.set(lesson="one-cell")  # it shows the quantizer on u: elevator (a field of the plots panel, not the panel)
    assert tab.frame.values.view_channel == 4
    assert not tab.session.mark.back.visible and "Modified" not in tab.controls.lesson_text.content


# ----- presenter mode -----------------------------------------------------------------------------------------------
def _font_sizes(fig) -> list:
    d = fig.to_plotly_json()["layout"]
    d.pop("template", None)
    out = []

    def walk(node, font=False):
        if isinstance(node, dict):
            for k, v in node.items():
                if font and k == "size":
                    out.append(v)
                walk(v, k == "font" or k.endswith("font"))
        elif isinstance(node, list):
            for v in node:
                walk(v)

    walk(d)
    return out


def test_presenter_mode_enlarges_every_plot_and_thickens_lines(tab):
    small = {name: h.figure for name, h in tab.session.plots.items()}
    assert min(s for f in small.values() for s in _font_sizes(f)) < PLOT_FONT  # the normal style is smaller
    tab.set(presenter=True)
    s = tab.session
    assert s.presenter.on and s.portrait.traj.thickness > 2.0 and s.portrait.true.thickness > 5.0
    assert s.presenter.style.visible and "font-size:max(16px" in s.presenter.style.content
    drawn = {name: h for name, h in s.plots.items() if h.figure.data}
    assert {"error", "bits", "bound"} <= set(drawn) and not set(drawn) & {v.name for v in KOOPMAN_VIEWS}
    for name, h in drawn.items():
        sizes = _font_sizes(h.figure)
        assert sizes and min(sizes) >= PLOT_FONT, name
        assert h.figure.layout.font.size >= PLOT_FONT
    err = s.plots["error"].figure
    widths = [t.line.width for t in err.data if t.mode and "lines" in t.mode and t.line.width]
    assert widths and min(widths) >= 3.0
    tab.set(presenter=False)
    assert not s.presenter.on and s.portrait.traj.thickness == 2.0 and not s.presenter.style.visible
    assert min(x for x in _font_sizes(s.plots["error"].figure)) < PLOT_FONT


def test_presenter_figure_raises_inline_font_spans():
    import plotly.graph_objects as go

    fig = go.Figure(layout=dict(title=dict(text="a <span style='font-size:12px'>b</span>")))
    out = presenter_figure(fig).layout  # (the title is drawn as a block of text at the top: an annotation)
    assert any("font-size:18px" in str(t) for t in [out.title.text, *(a.text for a in out.annotations)])
    assert "font-size:12px" in fig.layout.title.text  # the original is left alone


def test_presenter_is_a_settings_key_and_survives_a_lesson(tab):
    from app.settings.files import settings_json, values_from_json

    assert values_from_json(settings_json(Values(presenter=True))).presenter is True
    tab.set(presenter=True)
    tab.set(lesson="fig1")
    assert tab.controls["presenter"].value is True and tab.frame.values.presenter is True
    assert tab.frame.values.lesson == "fig1"


def test_dashboard_app_presenter_with_lesson():
    from app.dashboard import DashboardApp
    from app.dashboard.options import parser

    args = parser().parse_args(["--presenter", "--lesson", "fig2"])
    assert args.presenter and args.lesson == "fig2"
    app = DashboardApp(host="127.0.0.1", port=0, workers=0, presenter=True, lesson="fig2")
    try:
        assert app.defaults.presenter is True and app.defaults.lesson == "fig2"
        assert app.defaults.system == "boeing747"
    finally:
        app.stop()


def test_presenter_with_a_bad_lesson_is_one_line_and_exit_2():
    r = subprocess.run(
        [sys.executable, "-m", "app.dashboard", "--presenter", "--lesson", "nope", "--port", "0"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=HANG_S,
        env={**__import__("os").environ, "PYTHONPATH": str(ROOT)},
    )
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "unknown lesson 'nope'" in r.stderr, r.stderr


class _Recorder:
    """A stand-in for viser's handles: records panel commands, keeps assigned attributes."""

    def __init__(self, log=None, **attrs):
        self.log = log if log is not None else []
        self.__dict__.update(attrs)

    def set_width(self, w):
        self.log.append(("width", w))

    def minimize(self):
        self.log.append("minimize")

    def expand(self):
        self.log.append("expand")

    def on_click(self, f):
        self.click = f


class _Gui:
    def __init__(self):
        self.main = _Recorder()
        self.main_panel = self.main

    def add_html(self, content, visible=True):
        return _Recorder(content=content, visible=visible)

    def add_button(self, label, visible=True, hint=""):
        return _Recorder(label=label, visible=visible, order=0.0)


def test_presenter_shows_one_view_the_plot_or_the_scene():
    gui, panel = _Gui(), _Recorder()
    shown, looks = [], []
    portrait = _Recorder(set_presenter=lambda on: None, show=shown.append, look=lambda *a, **k: looks.append(a))
    changes = []
    lay = PresenterLayout(gui, panel, portrait, 640, _Recorder(order=3.0), lambda: changes.append(1))
    assert 3.0 < lay.switch.order < 3.001 and lay.switch.visible is False  # under the auto-play, above the code
    assert lay.apply(True)
    # both panels asked for more than any window, in the ratio the dock keeps when it scales them to fit
    assert gui.main.log == [("width", WIDE * LEFT_SHARE)] and panel.log[-1] == ("width", WIDE * (1 - LEFT_SHARE))
    assert shown[-1] is False  # one view: the scene hidden behind the plots (the dock keeps a strip of it)
    assert lay.switch.visible and lay.switch.label == SHOW_SCENE and lay.style.visible
    lay.switch.click(None)  # the one switch: the 3-D scene, the plots panel minimized, the box framed in it
    assert changes and lay.apply(True) and panel.log[-1] == "minimize"
    assert gui.main.log[-1] == ("width", LEFT_WIDTH) and shown[-1] is True and looks[-1] == (SCENE_ASPECT,)
    assert lay.switch.label == SHOW_PLOT and not lay.apply(True)
    lay.toggle()
    assert lay.apply(True) and panel.log[-2:] == ["expand", ("width", WIDE * (1 - LEFT_SHARE))]
    assert looks[-1] == ()  # the camera back where every tab starts
    assert lay.apply(False)  # off: the normal widths, the scene shown
    assert gui.main.log[-1] == ("width", 384) and panel.log[-1] == ("width", 640) and shown[-1] is True
    assert not lay.switch.visible and not lay.style.visible
    n = len(panel.log)
    assert not lay.apply(True, narrow=True) and len(panel.log) == n  # a phone has no presenter mode


# ----- auto-play ----------------------------------------------------------------------------------------------------
def _send(tab, handle, value):
    tab.ws.send(
        msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": handle._impl.uuid, "updates": {"value": value}})
    )


def test_auto_play_steps_b_from_1_one_drawn_frame_at_a_time_and_stops_at_a_user_change(tab, monkeypatch):
    import app.dashboard.presenter as presenter_module

    monkeypatch.setattr(presenter_module, "STEP_SECONDS", 2.0)  # room for the test's own steps on a busy machine
    s = tab.session
    drawn: list = []
    draw = s._draw

    def spy(frame, gen):  # which b each drawn frame showed, and whether every earlier b was drawn
        ok = draw(frame, gen)
        if ok and frame.stage == "current":
            drawn.append(frame.bits)
        return ok

    s._draw = spy
    tab.set(bits=8)
    s.play.press()
    assert s.play.state == "playing"
    wait_until(lambda: 4 in drawn, "auto-play drew b = 4")
    steps = [b for b in drawn if b <= 4]
    assert steps[-4:] == [1, 2, 3, 4]  # from 1, each b drawn before the next was set
    assert s.controls.play.label.startswith("■ pause")
    _send(tab, tab.controls["theta"], 0.3)  # the person moves another input in the browser
    wait_until(lambda: s.play.state == "paused", "the auto-play stopped")
    b = tab.wait().frame.values.bits
    assert s.play.stopped_by_user and s.play.wait_time() is None
    wait_until(lambda: "stopped by your change" in s.controls.play.label, "the button says so")
    time.sleep(2.5 * presenter_module.STEP_SECONDS)
    assert s.controls["bits"].value == b  # paused: b stays put
    s.play.press()  # resume: from the b shown, to 16, then off
    wait_until(lambda: s.play.state == "off", "the auto-play ran to b = 16")
    assert tab.wait().frame.values.bits == 16 and s.controls.play.label.startswith("▶ auto-play")
    assert drawn[-(16 - b) :] == list(range(b + 1, 17))


def test_the_request_path_hook_reads_the_live_path_and_fails_loudly_without_it(dashboard):
    from types import SimpleNamespace

    from app.dashboard.viserfix import connection_request

    assert connection_request(dashboard.server, -1) is None  # this viser keeps the raw connections: no such tab
    t = Tab(dashboard, "/v/kqbxtr")
    try:
        path, host = connection_request(dashboard.server, t.session.client.client_id)
        assert path == "/v/kqbxtr" and host == f"127.0.0.1:{dashboard.port}"
    finally:
        t.close()
    with pytest.raises(RuntimeError, match="viser internals changed"):
        connection_request(SimpleNamespace(_websock_server=SimpleNamespace()), 0)


def test_the_teaching_page_lists_every_lesson_and_shows_committed_screenshots():
    import re

    from app.lessons.table import LESSONS

    text = (ROOT / "docs" / "teaching.rst").read_text(encoding="utf-8")
    for les in LESSONS:
        assert f"``{les.name}``" in text, les.name
    images = re.findall(r"\.\. image:: \.\./(assets/[\w.-]+\.png)", text)
    assert len(images) >= 3
    for img in images:
        assert (ROOT / img).is_file(), img
