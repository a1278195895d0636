"""Dashboard server: a real viser server on 127.0.0.1 in-process, tabs connected over its websocket.

A tab is a plain websocket client speaking viser's protocol (it only reads what
the server sends), so every per-tab object -- controls, scene, plots, worker --
is built exactly as for a browser. Inputs are set from Python (``handle.value =``),
which runs the same callbacks a browser change would.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import msgspec
import numpy as np
import pytest
import viser
from websockets.sync.client import connect

from app.dashboard import DashboardApp

ROOT = Path(__file__).resolve().parents[1]
SMALL = dict(trajectories=10, steps=60, realizations=4)


class Tab:
    """A minimal viser client: connects, reports a camera, reads (and drops) every message until closed."""

    def __init__(self, url: str):
        self.ws = connect(url.replace("http://", "ws://"), subprotocols=[f"viser-v{viser.__version__}"],
                          max_size=None, open_timeout=20)
        self.received = 0
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()
        # viser counts a client as connected once it reports its camera (a browser does this at once)
        self.ws.send(msgspec.msgpack.encode({
            "type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0], "position": [3.0, 0.0, 0.0],
            "fov": 1.0, "near": 0.01, "far": 1000.0, "image_height": 900, "image_width": 1400,
            "look_at": [0.0, 0.0, 0.0], "up_direction": [0.0, 0.0, 1.0]}))

    def _read(self) -> None:
        try:
            while True:
                self.ws.recv()
                self.received += 1
        except Exception:
            pass

    def close(self) -> None:
        self.ws.close()


@pytest.fixture
def app():
    a = DashboardApp(host="127.0.0.1", port=0, workers=0)
    yield a
    a.stop()


def open_tab(app, n=1):
    tab = Tab(app.url)
    s = app.wait_for_sessions(n, timeout=30)
    sess = [x for x in s if x.client.client_id == max(y.client.client_id for y in s)][0]
    c = sess.controls
    c.set_scale(SMALL)
    c.mpc_steps.value = 15
    assert sess.wait_idle(120), "the first view was not drawn in time"
    return tab, sess


def figure_key(handle):
    return handle.figure.to_json()


def test_binds_localhost_and_hides_share_button(app):
    assert app.host == "127.0.0.1" and app.port > 0
    assert app.url == f"http://127.0.0.1:{app.port}"
    import urllib.request

    html = urllib.request.urlopen(app.url, timeout=10).read().decode()
    assert "<html" in html.lower()  # viser's own client, served offline
    theme = [m for m in app.server._websock_server._broadcast_buffer.message_from_id.values()
             if type(m).__name__ == "ThemeConfigurationMessage"]
    assert theme and all(m.show_share_button is False for m in theme)


def test_first_view_draws_scene_plots_and_summary(app):
    tab, s = open_tab(app)
    try:
        assert s.last_error is None and s.last_frame.complete
        p = s.portrait
        R, T = 4, 15
        assert p.traj.points.shape == (2 * R * T, 2, 3)  # ONE node: every realization of LS and BCLS
        assert p.true.points.shape == (T, 2, 3)
        assert p.sphere.opacity in (0.25, 0.12) and p.sphere.visible
        assert [lab.text for lab in p.axis_labels] == ["angle", "speed", "current"]
        assert "display scale" in p.scale_label.text and "δ(ε)" in p.sphere_label.text
        for name, h in s.plots.items():
            assert len(h.figure.data) > 0, name
        assert "ε states: angle" in s.controls.summary.content
        assert s.controls.status.content.startswith("ready")
        assert s.controls.progress.value == 100.0
        assert tab.received > 0  # the drawing reached the tab (batched websocket frames)
    finally:
        tab.close()


def test_word_length_change_moves_sphere_lines_and_marker(app):
    tab, s = open_tab(app)
    try:
        p = s.portrait
        traj_handle = p.traj
        pts, scale, err = p.traj.points.copy(), p.sphere.scale, s.plots["error"].figure
        eig = figure_key(s.plots["eigen"])
        assert [sh.x0 for sh in err.layout.shapes] == [4, 4]
        s.controls.bits.value = 10
        assert s.wait_idle(60)
        assert p.traj is traj_handle  # updated in place, not re-added
        assert not np.array_equal(p.traj.points, pts)
        assert p.sphere.scale < scale  # delta(eps) shrinks with more bits
        assert [sh.x0 for sh in s.plots["error"].figure.layout.shapes] == [10, 10]
        assert figure_key(s.plots["eigen"]) != eig
        assert s.last_frame.bits == 10 and "b = **10** bits" in s.controls.summary.content
    finally:
        tab.close()


def test_weight_change_redraws_cost_not_identification(app):
    tab, s = open_tab(app)
    try:
        cost = figure_key(s.plots["cost"])
        idents = dict(s.last_frame.idents)
        kinds = app.cache.kinds()
        s.controls.q_sliders[0].value = 1.5
        assert s.wait_idle(60)
        assert "Q = diag(31.6, 0.1, 0.1)" in s.controls.weights_note.content
        assert figure_key(s.plots["cost"]) != cost
        assert all(s.last_frame.idents[k] is idents[k] for k in idents)  # the same cached models
        assert app.cache.kinds()["ident"] == kinds["ident"]
    finally:
        tab.close()


def test_bad_inputs_show_plain_words_and_keep_the_last_view(app):
    tab, s = open_tab(app)
    try:
        c = s.controls
        view = s.portrait.view
        c.system.value = "custom"
        assert s.wait_idle(60)
        assert c.a_text.disabled is False and s.last_error is None  # a copy of the preset, editable
        view = s.portrait.view
        c.a_text.value = "1 0.1 0\n0 1 x\n0 0 1"
        assert s.wait_idle(60)
        assert c.error.visible and "Custom system: A row 2: '0 1 x' has an entry that is not a number" \
            in c.error.content
        assert s.portrait.view is view  # the last good view stays
        # unstable system: the data overflow is explained, the server lives on
        c.trajectories.value = 2
        c.steps.value = 2000
        c.a_text.value = "1.5 0 0\n0 1 0\n0 0 1"
        assert s.wait_idle(60)
        assert "spectral radius of A is 1.5" in c.error.content and c.error.visible
        # uncontrollable: a note, not an error
        c.steps.value = 60
        c.a_text.value = "0.5 0 0\n0 0.5 0\n0 0 0.5"
        c.b_text.value = "1 0\n0 1\n0 0"
        assert s.wait_idle(60)
        assert not c.error.visible and s.last_error is None
        assert "not controllable" in c.summary.content
        # a bad x0 typed in the MPC tab
        c.x0.value = "1, 2"
        assert s.wait_idle(60)
        assert "x0 needs 3 numbers" in c.error.content
        c.x0.value = "1, 0, 0"
        assert s.wait_idle(60) and not c.error.visible
    finally:
        tab.close()


def test_failing_mpc_is_reported_per_realization(app):
    tab, s = open_tab(app)
    try:
        c = s.controls
        c.system.value = "custom"
        assert s.wait_idle(60)
        # an unstable plant and a tiny input bound: no MPC can hold it, the loops fail one by one
        c.a_text.value = "1.5"
        c.b_text.value = "1"
        c.u_max.value = 0.05
        c.mpc_steps.value = 100
        assert s.wait_idle(60)
        assert s.last_error is None, s.last_error
        text = c.summary.content
        assert "4/4 (" in text and "diverged" in text and "LS MPC: " in text
        assert "its MPC failed: closed loop diverged" in text
        v = s.portrait.view
        assert v.failed > 0 and np.isfinite(v.segments).all() and v.axis_names == ("x1", "-", "-")
    finally:
        tab.close()


def test_boeing_axes_dropdown_picks_the_drawn_states(app):
    tab, s = open_tab(app)
    try:
        c = s.controls
        assert not c.axes.visible
        c.system.value = "boeing747"
        assert s.wait_idle(60)
        assert c.axes.visible and c.axes.options == ("u, w, q", "u, w, theta", "u, q, theta", "w, q, theta")
        assert len(c.q_sliders) == 4 and len(c.r_sliders) == 2 and c.x0.value == "1, 1, 0, 0"
        c.axes.value = "w, q, theta"
        assert s.wait_idle(60)
        assert [lab.text for lab in s.portrait.axis_labels] == ["w", "q", "theta"]
    finally:
        tab.close()


def test_newest_setting_wins(app):
    tab, s = open_tab(app)
    try:
        for b in (2, 9, 3, 12, 5, 7):
            s.controls.bits.value = b
            time.sleep(0.01)
        assert s.wait_idle(60)
        assert s.last_frame.bits == 7 and s.last_frame.complete
        assert [sh.x0 for sh in s.plots["error"].figure.layout.shapes] == [7, 7]
    finally:
        tab.close()


def test_paper_scale_button_sets_the_letters_size(app):
    tab, s = open_tab(app)
    try:
        c = s.controls
        c.set_scale({"trajectories": 200, "steps": 1000, "realizations": 50})
        v = c.values()
        assert (v.trajectories, v.steps, v.realizations) == (200, 1000, 50)
        c.set_scale(SMALL)  # back to small before the worker gets far
        assert s.wait_idle(120)
        assert s.last_frame.values.trajectories == 10
    finally:
        tab.close()


def test_two_tabs_keep_their_own_settings_and_share_the_cache(app):
    tab1, s1 = open_tab(app, 1)
    tab2, s2 = open_tab(app, 2)
    try:
        assert s1 is not s2 and s1.thread is not s2.thread
        hits = app.cache.hits
        s1.controls.bits.value = 11
        assert s1.wait_idle(60) and s2.wait_idle(60)
        assert s1.last_frame.bits == 11 and s2.last_frame.bits == 4
        assert s2.controls.bits.value == 4
        assert app.cache.hits > hits  # tab 1's b change reused tab 2's (equal) results
        tab1.close()
        deadline = time.time() + 20
        while len(app.sessions) > 1 and time.time() < deadline:
            time.sleep(0.05)
        assert list(app.sessions.values()) == [s2]
        s1.thread.join(10)
        assert not s1.thread.is_alive()  # the worker of a closed tab ends
    finally:
        tab2.close()


def test_worker_survives_unexpected_errors(app, monkeypatch):
    tab, s = open_tab(app)
    try:
        import app.dashboard as dash

        def boom(*a, **k):
            raise RuntimeError("simulated bug")
            yield  # pragma: no cover

        monkeypatch.setattr(dash, "iter_frames", boom)
        s.controls.bits.value = 6
        assert s.wait_idle(60)
        assert "internal error (RuntimeError): simulated bug" in s.controls.error.content
        monkeypatch.undo()
        s.controls.bits.value = 7
        assert s.wait_idle(60) and s.last_error is None and s.last_frame.bits == 7
    finally:
        tab.close()


def test_command_line_prints_url_and_stops_cleanly_on_ctrl_c():
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.Popen([sys.executable, "-m", "app.dashboard", "--port", "0", "--workers", "0"], cwd=ROOT,
                         env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = ""
        deadline = time.time() + 60
        while not line.startswith("qsid dashboard:") and time.time() < deadline:  # after viser's own banner
            line = p.stdout.readline()
        assert line.startswith("qsid dashboard: http://127.0.0.1:"), line
        time.sleep(0.5)
        p.send_signal(signal.SIGINT)
        out, err = p.communicate(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 0, err
    assert "Traceback" not in err and "stopping" in out


def test_command_line_rejects_unknown_system():
    r = subprocess.run([sys.executable, "-m", "app.dashboard", "--system", "nope"], cwd=ROOT, capture_output=True,
                       text=True, env=dict(os.environ, PYTHONPATH=str(ROOT)), timeout=60)
    assert r.returncode == 2 and "invalid choice: 'nope'" in r.stderr and "Traceback" not in r.stderr


def test_default_process_pool_gives_the_same_results():
    from concurrent.futures import ProcessPoolExecutor

    pooled = DashboardApp(host="127.0.0.1", port=0, workers=2)
    try:
        assert isinstance(pooled.executor, ProcessPoolExecutor) and pooled.tasks == 2
        tab, s = open_tab(pooled)
        try:
            s.controls.bits.value = 7
            assert s.wait_idle(120) and s.last_error is None
            rows = s.last_frame.rows
        finally:
            tab.close()
    finally:
        pooled.stop()
    from app.dashboard_compute import iter_frames
    from app.dashboard_state import SharedCache

    inline = list(iter_frames(s.last_frame.values, SharedCache()))[-1].rows
    for lab in ("LS", "BCLS"):
        for b in range(1, 17):
            assert rows[lab][b]["err_A"] == inline[lab][b]["err_A"]
            assert rows[lab][b]["mpc_cost"]["mean"] == pytest.approx(inline[lab][b]["mpc_cost"]["mean"], rel=1e-12)


def test_changes_from_other_threads_are_never_muted(app):
    """While the worker adapts the inputs to a new system, a person's change on another thread still counts."""
    tab, s = open_tab(app)
    try:
        c = s.controls
        g = s.generation
        c._muted_thread = -1  # as if the worker were inside set_system right now
        c.data_seed.value = 3
        assert s.generation == g + 1
        c._muted_thread = threading.get_ident()  # the muting thread's own adjustment is not a user change
        c.data_seed.value = 4
        assert s.generation == g + 1
        c._muted_thread = None
        c.data_seed.value = 5
        assert s.generation == g + 2 and s.wait_idle(60) and s.last_frame.values.data_seed == 5
    finally:
        tab.close()
