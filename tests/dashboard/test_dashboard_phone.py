"""The phone layout: told by the 3-D canvas's shape, one plot across the sheet, the box framed above the sheet.

Tabs here are websocket clients of an in-process server (``tests/support.py``) whose camera messages say how
large their canvas is, as viser's client does; the browser test (``tests/system/test_dashboard_legibility.py``)
measures the plots at 390 × 844 in Chromium.
"""

from __future__ import annotations

import math

import msgspec
import numpy as np
import pytest
from support import CAMERA, SMALL, Tab, wait_until

from app.dashboard.phone import NARROW, SETTINGS_LABELS, WIDE_AGAIN
from app.dashboard.scene import AXES_ENDS, FILL, FOV, FRAMED, camera_pose, drawn_points
from app.figures.presenter import PHONE_FONT, PHONE_WIDTH

#: An upright phone's canvas (390 × 844 CSS px at a device pixel ratio of 2).
PHONE = {**CAMERA, "image_width": 780, "image_height": 1688}
#: The same phone turned sideways.
SIDEWAYS = {**CAMERA, "image_width": 1688, "image_height": 780}


def _screen(pose, point, aspect):
    """(x, y) of ``point`` on the canvas, both in -1..1 (y up), for a camera ``pose`` (position, look_at, up)."""
    pos, target, up = (np.asarray(v, dtype=float) for v in pose)
    f = (target - pos) / np.linalg.norm(target - pos)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    d = np.asarray(point, dtype=float) - pos
    t = math.tan(FOV / 2) * float(d @ f)
    return float(d @ r) / (t * aspect), float(d @ u) / t


@pytest.mark.parametrize("aspect,free", [(1.35, 1.0), (1.8, 1.0), (0.46, 0.5), (390 / 664, 0.5)])
def test_the_camera_frames_the_box_in_the_free_part_of_the_canvas(aspect, free):
    pose = camera_pose(aspect, free)
    pts = [_screen(pose, p, aspect) for p in FRAMED]  # the unit box's corners and the axes' ends
    assert all(abs(x) <= 1 and 1 - 2 * free <= y <= 1 for x, y in pts), pts  # all of it in the free area
    cx, cy = _screen(pose, (0, 0, 0), aspect)
    assert abs(cx) < 1e-9 and cy == pytest.approx(1 - free)  # centred in it
    # and large in it: it fills the free area's width or its height (not a small picture in the middle)
    w = max(abs(x) for x, _ in pts)
    h = max(abs(y - (1 - free)) for _, y in pts) / free
    assert max(w, h) >= FILL - 0.02, (w, h)


def test_the_camera_comes_closer_to_small_loops_but_keeps_the_axes_ends_in_view():
    class View:  # the loops drawn (box units): small, near the origin
        segments = np.array([[[0.0, 0.0, 0.0], [0.3, -0.2, 0.1]]])
        true_segments = np.array([[[0.0, 0.0, 0.0], [0.2, 0.1, 0.0]]])
        start = (0.3, -0.2, 0.1)

    far, near = camera_pose(1.35), camera_pose(1.35, 1.0, drawn_points(View()))
    dist = [np.linalg.norm(np.subtract(p[0], p[1])) for p in (far, near)]
    assert dist[1] < 0.8 * dist[0]
    assert all(abs(x) <= 1 and abs(y) <= 1 for x, y in (_screen(near, p, 1.35) for p in AXES_ENDS))


def test_a_phone_tab_gets_the_phone_layout_and_a_sideways_one_the_laptop_layout(dashboard):
    assert 780 / 1688 < NARROW and 1688 / 780 > WIDE_AGAIN
    tab = Tab(dashboard, camera=PHONE)
    try:
        tab.set(mpc_steps=15, **SMALL)
        s, c = tab.session, tab.controls
        phone = s.ui.phone
        assert phone.narrow and phone.button.visible and phone.button.label == SETTINGS_LABELS[0]
        assert not c.tabs.visible and not c.summary_folder.visible  # the plots follow the slider in the sheet
        assert not c["presenter"].visible
        assert c.lesson_text.order > c["bits"].order  # the slider above the lesson's text
        err = s.plots["error"]
        lay = err.figure.layout
        rows = sorted((tuple(lay.yaxis.domain), tuple(lay.yaxis2.domain)))
        assert rows[0][1] < rows[1][0]  # Â's and B̂'s panels one above the other, each across the plot
        assert tuple(lay.xaxis.domain) == tuple(lay.xaxis2.domain) == (0.0, 1.0)
        assert err.aspect == pytest.approx(lay.height / PHONE_WIDTH, abs=1e-3) and err.aspect > 1.0
        assert lay.font.size >= PHONE_FONT
        tab.set(presenter=True)  # a phone has no presenter mode (a view link may carry it)
        assert not s.presenter.on and not s.presenter.switch.visible
        phone.toggle_settings()  # the one button: every setting back
        wait_until(lambda: c.tabs.visible and c.summary_folder.visible, "the settings shown")
        assert phone.button.label == SETTINGS_LABELS[1]
        tab.ws.send(msgspec.msgpack.encode(SIDEWAYS))  # turned sideways: viser's laptop layout, and ours
        wait_until(lambda: not phone.narrow, "the laptop layout")
        tab.wait()
        assert not phone.button.visible and c["presenter"].visible and c.tabs.visible
        assert s.presenter.on  # presenter mode, as the panel says, now that panels dock again
        tab.set(presenter=False)
        assert s.plots["error"].aspect == 0.62  # the view's own shape again
    finally:
        tab.close()


def test_a_laptop_tab_stays_a_laptop_tab_whatever_its_docked_canvas_looks_like(tab):
    phone = tab.session.ui.phone
    assert not phone.narrow and not phone.button.visible
    tab.ws.send(msgspec.msgpack.encode(PHONE))  # panels docked: the canvas is narrow, the window is not
    tab.set(bits=5)
    assert not phone.narrow and tab.controls.tabs.visible
