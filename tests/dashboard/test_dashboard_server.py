"""Dashboard server: a real viser server on 127.0.0.1 in-process, tabs connected over its websocket.

A tab (:class:`Tab`, the ``tab`` fixture) is a plain websocket client speaking
viser's protocol (it only reads what the server sends) plus the server-side
session viser built for it, so every per-tab object -- controls, scene, plots,
worker -- is built exactly as for a browser. Inputs are set from Python
(``tab.set(bits=10)``), which runs the same callbacks a browser change would.
The tests read only what a person sees: control values, the summary and error
texts, the plots' figures, the 3-D nodes, and the frame last drawn.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from support import HANG_S, ROOT, SMALL, marks, open_tab, wait_until

from app.dashboard import DashboardApp
from app.dashboard.session import iter_frames
from app.figures.registry import KOOPMAN_VIEWS, view_names
from app.frames.cache import SharedCache

KOOPMAN_NAMES = {v.name for v in KOOPMAN_VIEWS}


def test_binds_localhost_and_serves_the_client(dashboard):
    import urllib.request

    assert dashboard.host == "127.0.0.1" and dashboard.port > 0
    assert dashboard.url == f"http://127.0.0.1:{dashboard.port}"
    html = urllib.request.urlopen(dashboard.url, timeout=HANG_S).read().decode()
    assert "<html" in html.lower()  # viser's own client, served offline (the share button: browser test)


def test_first_view_draws_scene_plots_and_summary(tab):
    assert tab.error is None and tab.frame.complete
    p = tab.session.portrait
    R, T = 4, 15
    assert p.traj.points.shape == (2 * R * T, 2, 3)  # ONE node: every realization of LS and BCLS
    assert p.true.points.shape == (T, 2, 3)
    # at b = 4 the dc motor's bounds are larger than the view: no outline hides the loops, the caption under
    # the scene says so (not a label at the origin, on the loops)
    assert not p.sphere.visible and not p.realized.visible and "off scale" in p.scale_label.text
    assert not p.sphere_label.visible
    assert [lab.text for lab in p.axis_labels] == ["angle", "speed", "current"]
    assert "1 box unit =" in p.scale_label.text and "δ(ε)" in p.scale_label.text
    assert set(tab.session.plots) == set(view_names())
    for name, h in tab.session.plots.items():
        # data length and bandwidth: on demand; the nonlinear plants' views: drawn for a nonlinear plant only
        assert len(h.figure.data) > 0 or name in ("datalength", "bandwidth") or name in KOOPMAN_NAMES, name
    assert "ε states: angle" in tab.summary
    assert tab.controls.status.content.startswith("ready")
    assert tab.controls.progress.value == 100.0
    assert tab.received > 0  # the drawing reached the tab (batched websocket frames)


def test_word_length_change_moves_sphere_lines_and_marker(tab):
    p = tab.session.portrait
    traj_handle = p.traj
    pts, radius = p.traj.points.copy(), p.view.sphere_radius
    eig = tab.session.plots["eigen"].figure.to_json()
    assert marks(tab) == [4, 4]
    tab.set(bits=10)
    assert p.traj is traj_handle  # updated in place, not re-added
    assert not np.array_equal(p.traj.points, pts)
    assert p.view.sphere_radius < radius  # delta(eps) shrinks with more bits
    assert marks(tab) == [10, 10]
    assert tab.session.plots["eigen"].figure.to_json() != eig
    assert tab.frame.bits == 10 and "b = **10** bits" in tab.summary


# slow (~3 s): a tab's view computed in full twice
@pytest.mark.slow
def test_weight_change_redraws_cost_not_identification(tab):
    cost = tab.session.plots["cost"].figure.to_json()
    idents = dict(tab.frame.idents)
    tab.controls.q_sliders[0].value = 1.5  # a weight slider (they follow the system, not the table)
    tab.wait()
    assert "Q = diag(31.6, 0.1, 0.1)" in tab.controls.weights_note.content
    assert tab.session.plots["cost"].figure.to_json() != cost
    assert all(tab.frame.idents[k] is idents[k] for k in idents)  # the same models, from the shared cache


# slow (~8 s): the custom system computed in full before the typo
@pytest.mark.slow
def test_a_typo_in_a_custom_matrix_is_explained_and_the_last_view_stays(tab):
    tab.set(system="custom")
    assert tab.controls["a_text"].disabled is False and tab.error is None  # a copy of the preset, editable
    view = tab.session.portrait.view
    tab.set(a_text="1 0.1 0\n0 1 x\n0 0 1")
    assert "Custom system: A row 2: '0 1 x' has an entry that is not a number" in tab.error
    assert tab.session.portrait.view is view  # the last good view stays


# slow (~3 s): the custom system computed in full first
@pytest.mark.slow
def test_an_unstable_custom_system_is_explained(tab):
    tab.set(system="custom")
    tab.set(trajectories=2, steps=2000, a_text="1.5 0 0\n0 1 0\n0 0 1")
    assert "spectral radius of A is 1.5" in tab.error


def test_an_uncontrollable_system_gives_a_note_not_an_error(tab):
    tab.set(system="custom")
    tab.set(a_text="0.5 0 0\n0 0.5 0\n0 0 0.5", b_text="1 0\n0 1\n0 0")
    assert tab.error is None and "not controllable" in tab.summary


def test_a_bad_x0_is_explained_and_a_good_one_clears_it(tab):
    tab.set(x0="1, 2")
    assert "x0 needs 3 numbers" in tab.error
    tab.set(x0="1, 0, 0")
    assert tab.error is None


# slow (~4 s): 100-step loops of an unstable plant until they diverge
@pytest.mark.slow
def test_failing_mpc_is_reported_per_realization(tab):
    tab.set(system="custom")
    # an unstable plant and a tiny input bound: no MPC can hold it, the loops fail one by one
    tab.set(a_text="1.5", b_text="1", u_max=0.05, mpc_steps=100)
    assert tab.error is None
    assert "4/4 did not converge**: 4 diverged" in tab.summary and "LS MPC: " in tab.summary
    assert "its MPC failed: closed loop diverged" in tab.summary
    v = tab.session.portrait.view
    assert v.failed == 8 and np.isfinite(v.segments).all() and v.axis_names == ("x1", "time", "")


def test_boeing_axes_dropdown_picks_the_drawn_states(tab):
    c = tab.controls
    assert not c["axes"].visible
    tab.set(system="boeing747")
    assert c["axes"].visible and c["axes"].options == ("u, w, q", "u, w, theta", "u, q, theta", "w, q, theta")
    assert len(c.q_sliders) == 4 and len(c.r_sliders) == 2 and c["x0"].value == "1, 1, 0, 0"
    tab.set(axes="w, q, theta")
    assert [lab.text for lab in tab.session.portrait.axis_labels] == ["w", "q", "theta"]


def test_switching_system_then_changing_a_setting_draws_both(tab):
    """The panel adapts to a new system by itself; a person's next change is still drawn."""
    tab.set(system="boeing747", data_seed=3)
    assert tab.frame.system.name == "boeing747" and tab.frame.values.data_seed == 3
    assert tab.frame.values.x0 == "1, 1, 0, 0" and len(tab.frame.values.log_q) == 4


def test_newest_setting_wins(tab):
    for b in (2, 9, 3, 12, 5, 7):
        tab.controls["bits"].value = b
        time.sleep(0.01)
    tab.wait()
    assert tab.frame.bits == 7 and tab.frame.complete
    assert marks(tab) == [7, 7]


def test_paper_scale_values_then_back(tab):
    tab.controls["trajectories"].value = 200
    tab.controls["steps"].value = 1000
    tab.set(**SMALL)  # back to small before the worker gets far
    assert tab.frame.values.trajectories == 10 and tab.frame.values.steps == 60


def test_two_tabs_keep_their_own_settings(dashboard):
    tab1, tab2 = open_tab(dashboard), open_tab(dashboard)
    try:
        s1, s2 = tab1.session, tab2.session
        assert s1 is not s2 and s1.thread is not s2.thread
        tab1.set(bits=11)
        tab2.wait()
        assert tab1.frame.bits == 11 and tab2.frame.bits == 4 and tab2.controls["bits"].value == 4
        assert tab1.frame.idents["LS"] is not tab2.frame.idents["LS"]
        tab2.set(bits=11)  # equal settings: tab 2 gets tab 1's results from the shared cache
        assert tab2.frame.idents["LS"] is tab1.frame.idents["LS"]
        tab1.close()
        wait_until(lambda: len(dashboard.sessions) <= 1, "the closed tab's session removed")
        assert list(dashboard.sessions.values()) == [s2]
        s1.thread.join(HANG_S)
        assert not s1.thread.is_alive()  # the worker of a closed tab ends
    finally:
        tab2.close()


def test_worker_survives_unexpected_errors(tab, monkeypatch):
    import app.dashboard.session as session

    def boom(*a, **k):
        raise RuntimeError("simulated bug")
        yield  # pragma: no cover

    monkeypatch.setattr(session, "iter_frames", boom)
    tab.set(bits=6)
    assert "internal error (RuntimeError): simulated bug" in tab.error
    monkeypatch.undo()
    tab.set(bits=7)
    assert tab.error is None and tab.frame.bits == 7


# slow (~4 s): starts the command line as a process
@pytest.mark.slow
def test_command_line_prints_url_and_stops_cleanly_on_ctrl_c():
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.Popen(
        [sys.executable, "-m", "app.dashboard", "--port", "0", "--workers", "0"],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = ""
        deadline = time.time() + HANG_S
        while not line.startswith("qsid dashboard: http") and time.time() < deadline:  # past the compiling note
            line = p.stdout.readline()
        assert line.startswith("qsid dashboard: http://127.0.0.1:"), line
        time.sleep(0.5)
        p.send_signal(signal.SIGINT)
        out, err = p.communicate(timeout=HANG_S)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 0, err
    assert "Traceback" not in err and "stopping" in out


def test_command_line_rejects_unknown_system():
    r = subprocess.run(
        [sys.executable, "-m", "app.dashboard", "--system", "nope"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env=dict(os.environ, PYTHONPATH=str(ROOT)),
        timeout=HANG_S,
    )
    assert r.returncode == 2 and "unknown system 'nope'" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.slow
def test_default_process_pool_gives_the_same_results():
    import loky

    pooled = DashboardApp(host="127.0.0.1", port=0, workers=2)
    try:
        assert isinstance(pooled.executor, loky.ProcessPoolExecutor) and pooled.tasks == 2
        t = open_tab(pooled)
        try:
            t.set(bits=7)
            assert t.error is None
            frame = t.frame
        finally:
            t.close()
    finally:
        pooled.stop()
    inline = list(iter_frames(frame.values, SharedCache()))[-1].rows
    for lab in ("LS", "BCLS"):
        for b in range(1, 17):
            assert frame.rows[lab][b]["err_A"] == inline[lab][b]["err_A"]
            assert frame.rows[lab][b]["mpc_cost"]["mean"] == pytest.approx(
                inline[lab][b]["mpc_cost"]["mean"], rel=1e-12
            )
