"""The humanoid in the scene: the shared visual model (:mod:`dcmviz.visual`) through viser's
public API.

Every mesh is added once under ``/robot`` (a frame at the floating base) and then only moved:
the base frame takes the base pose, each mesh its pose relative to the base, sent only when it
changed (the locked upper body never moves relative to the base, so walking moves the legs'
meshes and one frame).  Clicking a mesh reports the push body it belongs to.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import viser

from dcmviz.backend import RobotPose
from dcmviz.robots import get_spec
from dcmviz.visual import RobotVisual

BodyClick = Callable[[str, viser.SceneNodePointerEvent], object]
MOVE_TOLERANCE = 1e-5  # m (and quaternion components): smaller changes are not sent
DEFAULT_BODY = "pelvis"


def push_body(ancestors: tuple[str, ...], bodies: dict[str, str]) -> str:
    """The push body (a key of ``bodies``, body → link) nearest up the tree from a mesh's link."""
    link_to_body = {link: body for body, link in bodies.items()}
    return next((link_to_body[a] for a in ancestors if a in link_to_body), DEFAULT_BODY)


def _click(body: str, callback: BodyClick) -> Callable[[viser.SceneNodePointerEvent], None]:
    return lambda event: callback(body, event)


class RobotView:
    """One humanoid under ``/robot``; :meth:`update` poses it from a :class:`RobotPose`."""

    def __init__(
        self,
        server: viser.ViserServer,
        visual: RobotVisual,
        on_body_click: BodyClick | None = None,
    ) -> None:
        self.server = server
        self.visual = visual
        self.model = visual.model_name
        bodies = get_spec(self.model).bodies
        self.bodies = tuple(push_body(m.ancestors, bodies) for m in visual.meshes)
        self._joints: dict[str, float] | None = None
        rest = visual.in_base({})
        self._position = rest.position.copy()
        self._wxyz = rest.wxyz.copy()
        with server.atomic():
            self.root = server.scene.add_frame("/robot", show_axes=False)
            self.meshes: list[viser.MeshHandle] = []
            for i, mesh in enumerate(visual.meshes):
                r, g, b, a = mesh.color
                handle = server.scene.add_mesh_simple(
                    f"/robot/{mesh.name}", mesh.vertices, mesh.faces, color=(r, g, b),
                    opacity=None if a >= 255 else a / 255.0,
                    position=rest.position[i], wxyz=rest.wxyz[i],
                )  # fmt: skip
                if on_body_click is not None:
                    handle.on_click(_click(self.bodies[i], on_body_click))
                self.meshes.append(handle)

    def update(self, pose: RobotPose) -> int:
        """Pose the robot; returns how many meshes moved relative to the base."""
        changed = np.zeros(len(self.meshes), bool)
        if pose.joints != self._joints:  # the kinematics outside the scene's lock
            self._joints = dict(pose.joints)
            poses = self.visual.in_base(pose.joints)
            changed = (np.abs(poses.position - self._position).max(axis=1) > MOVE_TOLERANCE) | (
                np.abs(poses.wxyz - self._wxyz).max(axis=1) > MOVE_TOLERANCE
            )
            self._position[changed] = poses.position[changed]
            self._wxyz[changed] = poses.wxyz[changed]
        with self.server.atomic():
            self.root.position = np.asarray(pose.base_position, float)
            self.root.wxyz = np.asarray(pose.base_wxyz, float)
            for i in np.flatnonzero(changed):
                self.meshes[i].position = self._position[i]
                self.meshes[i].wxyz = self._wxyz[i]
        return int(changed.sum())

    def set_visible(self, visible: bool) -> None:
        if self.root.visible != visible:
            self.root.visible = visible

    def remove(self) -> None:
        """Remove the robot (the root node takes every mesh with it)."""
        self.root.remove()
