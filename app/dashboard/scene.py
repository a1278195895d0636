"""The 3-D phase portrait of one browser tab, drawn with viser scene nodes.

Nodes are created once per tab and then updated in place (``handle.points``,
``handle.colors``, ``handle.scale``, ``label.text``); a node is re-added only
when the number of line segments changes (more realizations or MPC steps).
The arrays come from :func:`app.figures.phase_scene.scene_view`; colours from
:mod:`app.figures.palette` (the same as the plots').
"""

from __future__ import annotations

import numpy as np

from app.figures.palette import rgb
from app.figures.phase_scene import SceneView

__all__ = ["PhasePortrait"]

AXIS = 1.25  # half length of the drawn axes, in box units
_GREY = rgb("axes")
_SPHERE = rgb("bound")
_CAPPED = rgb("bound_capped")


class PhasePortrait:
    """Trajectories, true-model trajectory, start point, axes with labels and the bound sphere.

    Parameters
    ----------
    scene : viser.SceneApi
        ``client.scene`` of the tab (each tab draws its own scene).
    prefix : str
        Scene-tree folder of every node.
    """

    def __init__(self, scene, prefix: str = "/qsid"):
        self.scene = scene
        self.p = prefix
        self.view: SceneView | None = None
        self.draws = 0
        ax = np.zeros((3, 2, 3), dtype=np.float32)
        for i in range(3):
            ax[i, 0, i], ax[i, 1, i] = -AXIS, AXIS
        self.axes = scene.add_line_segments(f"{prefix}/axes", ax, np.array(_GREY, dtype=np.uint8),
                                            thickness=1.0, thickness_units="screen")
        ends = np.eye(3) * (AXIS + 0.08)
        self.axis_labels = [
            scene.add_label(f"{prefix}/axis_{i}", "x" + str(i + 1), position=tuple(ends[i]), anchor="center-left",
                            font_screen_scale=1.1)
            for i in range(3)
        ]
        self.scale_label = scene.add_label(f"{prefix}/scale", "", position=(0.0, 0.0, -AXIS - 0.05),
                                           anchor="top-center", font_screen_scale=0.85)
        self.sphere = scene.add_icosphere(f"{prefix}/bound", radius=1.0, color=_SPHERE, opacity=0.25,
                                          subdivisions=3, scale=1e-3, cast_shadow=False, receive_shadow=False)
        self.sphere_label = scene.add_label(f"{prefix}/bound_label", "", position=(0.0, 0.0, 0.0),
                                            anchor="bottom-center", font_screen_scale=0.9)
        self.start = scene.add_icosphere(f"{prefix}/x0", radius=0.035, color=(0, 0, 0), subdivisions=2,
                                         cast_shadow=False, receive_shadow=False)
        self.start_label = scene.add_label(f"{prefix}/x0_label", "x0", position=(0.0, 0.0, 0.0),
                                           anchor="bottom-right", font_screen_scale=1.0)
        empty = np.zeros((1, 2, 3), dtype=np.float32)
        self.traj = self._add_traj(empty, np.zeros((1, 2, 3), dtype=np.uint8))
        self.true = self._add_true(empty)

    # ----- nodes ------------------------------------------------------------------------
    def _add_traj(self, pts, cols):
        return self.scene.add_line_segments(f"{self.p}/trajectories", pts, cols, thickness=2.0,
                                            thickness_units="screen")

    def _add_true(self, pts):
        return self.scene.add_line_segments(f"{self.p}/true_model", pts, np.array(rgb("true"), dtype=np.uint8),
                                            thickness=3.0, thickness_units="screen")

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
        r = v.sphere_radius
        self.sphere.scale = max(r, 1e-4)
        self.sphere.visible = r > 0
        # a bound larger than the view is drawn capped, fainter and orange (the label says so)
        self.sphere.color = _CAPPED if v.sphere_capped else _SPHERE
        self.sphere.opacity = 0.12 if v.sphere_capped else 0.25
        if v.delta is None:
            stext = "δ(ε): no bound at this b"
        elif v.sphere_capped:
            stext = f"δ(ε) = {v.delta:.3g} = {v.delta / v.scale:.3g} box units (sphere capped)"
        else:
            stext = f"δ(ε) = {v.delta:.3g}"
        self.sphere_label.text = stext
        self.sphere_label.position = (0.0, 0.0, float(max(r, 0.02)))
        extra = []
        if v.failed:
            extra.append(f"{v.failed} failed loops hidden")
        if v.clipped:
            extra.append(f"{v.clipped} loops leave the view (clipped)")
        self.scale_label.text = (f"{v.polylines} closed loops · display scale: 1 box unit = {v.scale:.3g}"
                                 + (" · " + " · ".join(extra) if extra else ""))
        self.view = v
        self.draws += 1
