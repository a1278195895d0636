"""The 3-D phase portrait of one browser tab, drawn with viser scene nodes.

Nodes are created once per tab and then updated in place (``handle.points``,
``handle.colors``, ``handle.scale``, ``label.text``); a node is re-added only
when the number of line segments changes (more realizations or MPC steps).
The arrays come from :func:`app.figures.phase_scene.scene_view`; colours from
:mod:`app.figures.palette` (the same as the plots').
"""

from __future__ import annotations

import math

import numpy as np

from app.figures.palette import rgb
from app.figures.phase_scene import SceneView

__all__ = ["PhasePortrait", "camera_pose", "drawn_points", "VIEW_FROM", "FOV", "FRAMED"]

PRESENTER_SCALE = 1.8  # presenter mode: lines and labels of the 3-D scene this much thicker / bigger
AXIS = 1.25  # half length of the drawn axes, in box units
_GREY = rgb("axes")
_SPHERE = rgb("bound")
_REALIZED = rgb("realized")
_NONE = np.zeros((1, 2, 3), dtype=np.float32)

#: The direction the camera looks at the box from (every new tab starts there, 3.1 box units away).
VIEW_FROM = (1.7, -2.2, 1.4)
#: viser's vertical field of view (radians; three.js's default 75°).
FOV = math.radians(75.0)
#: What the camera frames at least (box units): the axes' ends, where their labels are.
AXES_ENDS = np.vstack([AXIS * np.eye(3), -AXIS * np.eye(3)])
#: ... and, before anything is drawn, the corners of the unit box the loops lie in.
FRAMED = np.vstack([AXES_ENDS, [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]])
#: Share of the free area the framed points may fill (the labels beside the axes' ends need the rest).
FILL = 0.85


def _pose(d: float, free: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Camera ``d`` away along :data:`VIEW_FROM`, its target lowered so that the free area is centred:
    (position, target, forward, screen up)."""
    back = np.asarray(VIEW_FROM, dtype=float)
    back /= np.linalg.norm(back)  # from the target to the camera
    up = np.array([0.0, 0.0, 1.0]) - back[2] * back
    up /= np.linalg.norm(up)  # the screen's up direction, in the world
    target = -up * (1.0 - free) * d * math.tan(FOV / 2)  # the free area's centre lies this far above the middle
    return target + back * d, target, -back, up


def _fits(d: float, aspect: float, free: float, points: np.ndarray) -> bool:
    pos, _, fwd, up = _pose(d, free)
    right = np.cross(fwd, up)
    rel = points - pos
    depth = (rel @ fwd) * math.tan(FOV / 2)
    x, y = (rel @ right) / (depth * aspect), (rel @ up) / depth  # -1..1 across the canvas
    mid = 1.0 - free  # the free area's centre
    return bool(np.all(np.abs(x) <= FILL) and np.all(np.abs(y - mid) <= FILL * free))


def drawn_points(view: SceneView | None) -> np.ndarray:
    """The points a camera frames for ``view``: the axes' ends and the corners of the drawn loops' bounding box
    (before anything is drawn: the unit box, :data:`FRAMED`)."""
    if view is None:
        return FRAMED
    pts = np.vstack([view.segments.reshape(-1, 3), view.true_segments.reshape(-1, 3), np.reshape(view.start, (1, 3))])
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if pts.shape[0] == 0:
        return FRAMED
    lo, hi = np.clip(pts.min(axis=0), -1.0, 1.0), np.clip(pts.max(axis=0), -1.0, 1.0)
    box = [(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    return np.vstack([AXES_ENDS, box])


def camera_pose(
    aspect: float, free: float = 1.0, points: np.ndarray = FRAMED
) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """(position, look_at, up) of a camera that frames ``points`` (box units) in the part of the canvas the
    panels leave free: the top ``free`` share of its height, on a canvas ``aspect`` (width / height) wide.

    The box is seen from :data:`VIEW_FROM`, its origin in the middle of the free area, as close as that area
    allows (``points`` fill :data:`FILL` of its height or of its width, whichever is reached first); with
    ``free`` < 1 the look-at point moves down so that the origin is centred in the free area above (a phone:
    the bottom sheet covers the rest).
    """
    lo, hi = 0.5, 50.0
    for _ in range(40):  # the nearest distance at which everything fits (it fits farther away too)
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if _fits(mid, aspect, free, points) else (mid, hi)
    pos, target, _, _ = _pose(hi, free)
    return tuple(map(float, pos)), tuple(map(float, target)), (0.0, 0.0, 1.0)


class PhasePortrait:
    """Trajectories, true-model trajectory, start point, axes with labels and the bound sphere.

    Parameters
    ----------
    scene : viser.SceneApi
        ``client.scene`` of the tab (each tab draws its own scene).
    prefix : str
        Scene-tree folder of every node.
    """

    def __init__(self, scene, prefix: str = "/qsid", camera=None):
        self.scene = scene
        self.camera = camera  # the tab's viewer camera (None: the camera is left alone)
        self.p = prefix
        self.root = scene.add_frame(prefix, show_axes=False)  # every node below: hidden and shown at once
        self.view: SceneView | None = None
        self.draws = 0
        self.thick = 1.0  # line widths and label sizes x this (presenter mode: PRESENTER_SCALE)
        ax = np.zeros((3, 2, 3), dtype=np.float32)
        for i in range(3):
            ax[i, 0, i], ax[i, 1, i] = -AXIS, AXIS
        self.axes = scene.add_line_segments(
            f"{prefix}/axes", ax, np.array(_GREY, dtype=np.uint8), thickness=1.0, thickness_units="screen"
        )
        ends = np.eye(3) * (AXIS + 0.08)
        self.axis_labels = [
            scene.add_label(
                f"{prefix}/axis_{i}",
                "x" + str(i + 1),
                position=tuple(ends[i]),
                anchor="center-left",
                font_screen_scale=1.1,
            )
            for i in range(3)
        ]
        self.scale_label = scene.add_label(
            f"{prefix}/scale", "", position=(0.0, 0.0, -AXIS - 0.05), anchor="top-center", font_screen_scale=0.85
        )
        self.sphere = self._add_circles("bound", _NONE, _SPHERE)
        self.realized = self._add_circles("bound_realized", _NONE, _REALIZED)
        self.ref_path = self._add_circles("reference", _NONE, rgb("theory"))  # a time-varying reference
        self.marks = scene.add_point_cloud(
            f"{prefix}/time_marks",
            np.zeros((1, 3), dtype=np.float32),
            np.array(rgb("true"), dtype=np.uint8),
            point_size=0.035,
            point_shape="circle",
        )
        self.sphere_label = scene.add_label(
            f"{prefix}/bound_label", "", position=(0.0, 0.0, 0.0), anchor="bottom-center", font_screen_scale=0.9
        )
        self.start = scene.add_icosphere(
            f"{prefix}/x0", radius=0.035, color=(0, 0, 0), subdivisions=2, cast_shadow=False, receive_shadow=False
        )
        self.start_label = scene.add_label(
            f"{prefix}/x0_label", "x0", position=(0.0, 0.0, 0.0), anchor="bottom-right", font_screen_scale=1.0
        )
        empty = np.zeros((1, 2, 3), dtype=np.float32)
        self.traj = self._add_traj(empty, np.zeros((1, 2, 3), dtype=np.uint8))
        self.true = self._add_true(empty)

    # ----- nodes ------------------------------------------------------------------------
    def _add_circles(self, name: str, pts, color):
        """Thin outline circles of a bound (unobtrusive: never hides the loops)."""
        return self.scene.add_line_segments(
            f"{self.p}/{name}", pts, np.array(color, dtype=np.uint8), thickness=1.2, thickness_units="screen"
        )

    def _set_circles(self, attr: str, name: str, pts, color) -> None:
        node = getattr(self, attr)
        if pts.shape[0] == 0:
            node.visible = False
            return
        if node.points.shape != pts.shape:
            node = self._add_circles(name, pts, color)
            setattr(self, attr, node)
        else:
            node.points = pts
        node.visible = True

    def _add_traj(self, pts, cols):
        return self.scene.add_line_segments(
            f"{self.p}/trajectories", pts, cols, thickness=2.0 * self.thick, thickness_units="screen"
        )

    def _add_true(self, pts):
        return self.scene.add_line_segments(
            f"{self.p}/true_model",
            pts,
            np.array(rgb("true"), dtype=np.uint8),
            thickness=5.0 * self.thick,
            thickness_units="screen",
        )

    def set_presenter(self, on: bool) -> None:
        """Thicker loops and bigger labels (presenter mode), or the normal ones."""
        self.thick = PRESENTER_SCALE if on else 1.0
        self.traj.thickness = 2.0 * self.thick
        self.true.thickness = 5.0 * self.thick
        labels = (*self.axis_labels, self.start_label, self.scale_label, self.sphere_label)
        for lab, base in zip(labels, (1.1, 1.1, 1.1, 1.0, 0.85, 0.9)):
            lab.font_screen_scale = base * self.thick

    def show(self, on: bool) -> None:
        """Show or hide the whole portrait (presenter mode hides it while the plot fills the window)."""
        if self.root.visible != on:
            self.root.visible = on

    def look(self, aspect: float | None = None, free: float = 1.0) -> None:
        """Point the camera at the box: the loops drawn now framed in a free area (:func:`camera_pose`), or,
        without ``aspect``, from where every new tab starts."""
        if self.camera is None:
            return
        pose: tuple[tuple[float, ...], ...] = (VIEW_FROM, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
        if aspect is not None:  # what is drawn now, as large as the free area allows
            pose = camera_pose(aspect, free, drawn_points(self.view))
        pos, target, up = pose
        self.camera.up_direction = up
        self.camera.position = pos  # (moves the look-at point along: it is set after)
        self.camera.look_at = target

    # ----- drawing ----------------------------------------------------------------------
    def draw(self, v: SceneView) -> None:
        """Update every node to ``v`` (in place when shapes allow)."""
        if self.traj.points.shape == v.segments.shape:
            self.traj.points = v.segments
            self.traj.colors = v.colors
        else:  # re-adding under the same name replaces the node (the old handle is dropped)
            self.traj = self._add_traj(v.segments, v.colors)
        if self.true.points.shape == v.true_segments.shape:
            self.true.points = v.true_segments
        else:
            self.true = self._add_true(v.true_segments)
        for lab, name in zip(self.axis_labels, v.axis_names):
            if lab.text != name:
                lab.text = name
        self.start.position = tuple(float(x) for x in v.start)
        self.start_label.position = tuple(float(x) for x in v.start)
        self._set_circles("sphere", "bound", v.bound_circles, _SPHERE)
        self._set_circles("realized", "bound_realized", v.realized_circles, _REALIZED)
        self._set_circles("ref_path", "reference", v.ref_segments, rgb("theory"))
        # a bound too large to draw has no circle to label: its text joins the caption under the scene (a
        # label at the origin would sit on the loops)
        off_scale = v.show_bound and v.bound_circles.shape[0] == 0
        self.sphere_label.text = v.bound_text if v.show_bound and not off_scale else ""
        self.sphere_label.visible = v.show_bound and not off_scale
        r = min(v.sphere_radius, 1.6) if v.bound_circles.shape[0] else 0.0
        self.sphere_label.position = (0.0, 0.0, float(max(r, 0.02)))
        if v.time_marks.shape[0] and v.time_marks.shape != self.marks.points.shape:
            self.marks = self.scene.add_point_cloud(
                f"{self.p}/time_marks",
                v.time_marks,
                np.array(rgb("true"), dtype=np.uint8),
                point_size=0.035,
                point_shape="circle",
            )
        elif v.time_marks.shape[0]:
            self.marks.points = v.time_marks
        self.marks.visible = v.time_marks.shape[0] > 0
        ax = np.zeros((3, 2, 3), dtype=np.float32)
        for i, name in enumerate(v.axis_names):  # an unused axis (1-state systems) is not drawn
            self.axis_labels[i].visible = bool(name)
            if name:
                ax[i, 0, i], ax[i, 1, i] = (0.0 if name == "time" else -AXIS), AXIS
        if not np.array_equal(self.axes.points, ax):
            self.axes.points = ax
        extra = []
        if v.failed:
            extra.append(f"{v.failed} failed loops hidden")
        if v.not_converged:
            extra.append(f"{v.not_converged} loops do not converge on the true plant")
        if v.clipped:
            extra.append(f"{v.clipped} loops leave the view (clipped)")
        same = "" if v.polylines == v.realizations else f" ({v.realizations} computed, identical without dither)"
        # one fact per line (viser splits labels at newlines): a long single line was cut at the canvas edge
        self.scale_label.text = (
            "\n".join(v.caption)
            if v.caption
            else "\n".join(
                [
                    f"{v.polylines} distinct closed loops{same}",
                    f"dots every {v.mark_every} steps on the true-model loop (until it converges)",
                    f"1 box unit = {v.scale:.3g}",
                    *extra,
                    *(v.bound_text.splitlines() if off_scale else []),
                ]
            )
        )
        self.view = v
        self.draws += 1
