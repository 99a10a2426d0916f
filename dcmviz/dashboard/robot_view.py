"""The humanoid in the scene: the shared visual model (:mod:`dcmviz.robots.visual`) through viser's
public API.

Every mesh is added once under ``/robot`` (a frame at the floating base) and then only moved.
The meshes form viser's scene tree along the kinematic tree,
nodes named by mesh index (``/robot/0/1/…``: every update carries its path), each posed
relative to its parent mesh: a revolute joint then changes only its child's
orientation, so walking sends one small message per moving leg link and two for the base, and
nothing for the locked upper body.  A pose is sent only when it moved more than
MOVE_TOLERANCE.  Clicking a mesh reports the push body it belongs to.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import viser

from dcmviz.robots import Robot
from dcmviz.robots.pose import RobotPose

BodyClick = Callable[[str, viser.SceneNodePointerEvent], object]
BodyDrag = Callable[[str, viser.SceneNodeDragEvent], object]
MOVE_TOLERANCE = 2e-4  # m (and quaternion components, ≈ 0.02°): smaller changes are not sent
DEFAULT_BODY = "pelvis"


def push_body(ancestors: tuple[str, ...], bodies: dict[str, str]) -> str:
    """The push body (a key of ``bodies``, body → link) nearest up the tree from a mesh's link."""
    link_to_body = {link: body for body, link in bodies.items()}
    return next((link_to_body[a] for a in ancestors if a in link_to_body), DEFAULT_BODY)


def parent_meshes(links: tuple[str, ...], ancestors: tuple[tuple[str, ...], ...]) -> list[int]:
    """For each mesh, the index of the mesh it hangs from in the scene tree (-1: the base): the
    first mesh on the nearest ancestor link that has one (a link's later meshes hang from its
    first)."""
    first: dict[str, int] = {}
    for i, link in enumerate(links):
        first.setdefault(link, i)
    parents = []
    for i, (link, up) in enumerate(zip(links, ancestors, strict=True)):
        if first[link] != i:
            parents.append(first[link])
            continue
        parents.append(next((first[a] for a in up if a != link and a in first), -1))
    return parents


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton products of (n, 4) wxyz quaternions."""
    w1, x1, y1, z1 = a.T
    w2, x2, y2, z2 = b.T
    return np.stack([
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ], axis=1)  # fmt: skip


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate (n, 3) vectors by (n, 4) wxyz quaternions."""
    w, u = q[:, :1], q[:, 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def relative_poses(
    position: np.ndarray, wxyz: np.ndarray, parents: list[int]
) -> tuple[np.ndarray, np.ndarray]:
    """Each mesh's pose in its parent mesh's frame (in the base frame for parent -1)."""
    idx = np.asarray(parents)
    has = idx >= 0
    p_par = np.where(has[:, None], position[idx], 0.0)
    q_par = np.where(has[:, None], wxyz[idx], [1.0, 0.0, 0.0, 0.0])
    q_inv = q_par * [1.0, -1.0, -1.0, -1.0]
    rel_q = quat_multiply(q_inv, wxyz)
    rel_q *= np.where(rel_q[:, :1] < 0.0, -1.0, 1.0)  # one sign: tolerance compares components
    return quat_rotate(q_inv, position - p_par), rel_q


def _click(body: str, callback: BodyClick) -> Callable[[viser.SceneNodePointerEvent], None]:
    return lambda event: callback(body, event)


def _drag(body: str, callback: BodyDrag) -> Callable:
    async def on_drag(event: viser.SceneNodeDragEvent) -> None:  # async: phases in order
        callback(body, event)

    return on_drag


class RobotView:
    """One humanoid under ``/robot``; :meth:`update` poses it from a :class:`RobotPose`."""

    def __init__(
        self,
        server: viser.ViserServer,
        robot: Robot,
        on_body_click: BodyClick | None = None,
        on_body_drag: BodyDrag | None = None,
    ) -> None:
        self.server = server
        self.visual = visual = robot.visual
        self.model = robot.name
        bodies = robot.spec.bodies
        self.bodies = tuple(push_body(m.ancestors, bodies) for m in visual.meshes)
        self._joints: dict[str, float] | None = None
        self.parents = parent_meshes(
            tuple(m.link for m in visual.meshes), tuple(m.ancestors for m in visual.meshes)
        )
        rest = visual.in_base({})
        self._position, self._wxyz = relative_poses(rest.position, rest.wxyz, self.parents)
        paths: list[str] = []
        for i in range(len(visual.meshes)):  # parents come before their children
            parent = self.parents[i]  # short names: every pose update carries its node's path
            paths.append(("/robot" if parent < 0 else paths[parent]) + f"/{i}")
        order = sorted(range(len(paths)), key=lambda i: paths[i].count("/"))
        with server.atomic():
            self.root = server.scene.add_frame("/robot", show_axes=False)
            self.meshes: list[viser.MeshHandle] = [None] * len(paths)  # type: ignore[list-item]
            for i in order:
                mesh = visual.meshes[i]
                r, g, b, a = mesh.color
                handle = server.scene.add_mesh_simple(
                    paths[i], mesh.vertices, mesh.faces, color=(r, g, b),
                    opacity=None if a >= 255 else a / 255.0,
                    position=self._position[i], wxyz=self._wxyz[i],
                )  # fmt: skip
                if on_body_click is not None:
                    handle.on_click(_click(self.bodies[i], on_body_click))
                if on_body_drag is not None:
                    handle.on_drag("left")(_drag(self.bodies[i], on_body_drag))
                self.meshes[i] = handle
        self._base = (np.full(3, np.inf), np.zeros(4))

    def update(self, pose: RobotPose) -> int:
        """Pose the robot; returns how many meshes moved relative to the base."""
        changed = np.zeros(len(self.meshes), bool)
        if pose.joints != self._joints:  # the kinematics outside the scene's lock
            self._joints = dict(pose.joints)
            poses = self.visual.in_base(pose.joints)
            position, wxyz = relative_poses(poses.position, poses.wxyz, self.parents)
            moved = np.abs(position - self._position).max(axis=1) > MOVE_TOLERANCE
            turned = np.abs(wxyz - self._wxyz).max(axis=1) > MOVE_TOLERANCE
            self._position[moved], self._wxyz[turned] = position[moved], wxyz[turned]
            changed = moved | turned
        base_p = np.asarray(pose.base_position, float)
        base_q = np.asarray(pose.base_wxyz, float)
        with self.server.atomic():
            if np.abs(base_p - self._base[0]).max() > MOVE_TOLERANCE:
                self.root.position = base_p
                self._base = (base_p, self._base[1])
            if np.abs(base_q - self._base[1]).max() > MOVE_TOLERANCE:
                self.root.wxyz = base_q
                self._base = (self._base[0], base_q)
            for i in np.flatnonzero(changed):
                if moved[i]:
                    self.meshes[i].position = self._position[i]
                if turned[i]:
                    self.meshes[i].wxyz = self._wxyz[i]
        return int(changed.sum())

    def set_visible(self, visible: bool) -> None:
        if self.root.visible != visible:
            self.root.visible = visible

    def remove(self) -> None:
        """Remove the robot (the root node takes every mesh with it)."""
        self.root.remove()
