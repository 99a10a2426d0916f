"""The humanoid drawn with its meshes (``viser.extras.ViserUrdf`` + yourdfpy).

The simulated model locks the upper body at its nominal posture (:mod:`dcmviz.sim.robots`); the
view draws the full URDF with those joints at the same nominal angles and the legs and base from
the simulation.  Clicking a mesh reports the push body it belongs to.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable

import numpy as np
import viser
import viser.transforms as vtf
import yourdfpy
from viser.extras import ViserUrdf

from dcmviz.robots import get_spec
from dcmviz.sim.robots import robots_dir

URDFS = {
    "talos": "talos_data/robots/talos_reduced.urdf",
    "g1": "g1_description/urdf/g1_29dof_rev_1_0.urdf",
}


def package_handler(fname: str) -> str:
    """Resolve ``package://example-robot-data/...`` against the installed example-robot-data."""
    if fname.startswith("package://"):
        share = os.path.dirname(os.path.dirname(robots_dir()))
        return os.path.join(share, fname[len("package://") :])
    return fname


@functools.cache
def load_urdf(model: str) -> yourdfpy.URDF:
    """The full visual URDF of ``model`` with meshes, loaded once per process."""
    return yourdfpy.URDF.load(
        os.path.join(robots_dir(), URDFS[model]),
        filename_handler=package_handler,
        build_collision_scene_graph=False,
        load_collision_meshes=False,
    )


@functools.cache
def nominal_angles(model: str) -> dict[str, float]:
    """Nominal joint angles (rad) the simulation locks the upper body at."""
    try:
        from dcmviz.sim.robots import robot_source  # the simulation's own nominal posture

        return dict(robot_source(model).nominal)
    except Exception:  # noqa: BLE001 - drawing must not depend on a private helper
        return {}


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    """Quaternion (w, x, y, z) of a rotation by ``angle`` about the unit ``axis``."""
    h = 0.5 * angle
    return np.concatenate([[np.cos(h)], np.sin(h) * axis])


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a ⊗ b of (w, x, y, z) quaternions."""
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ]
    )


def _click_handler(
    body: str, callback: Callable[[str, viser.SceneNodePointerEvent], None]
) -> Callable[[viser.SceneNodePointerEvent], None]:
    return lambda event: callback(body, event)


class RobotView:
    """One humanoid in the scene under ``/robot``; :meth:`update` poses it."""

    def __init__(
        self,
        server: viser.ViserServer,
        model: str,
        on_body_click: Callable[[str, viser.SceneNodePointerEvent], None] | None = None,
    ) -> None:
        self.server = server
        self.model = model
        self.urdf = load_urdf(model)
        self.spec = get_spec(model)
        self.root = server.scene.add_frame("/robot", show_axes=False)
        self.view = ViserUrdf(server, self.urdf, root_node_name="/robot")
        self.joint_names = tuple(self.urdf.actuated_joint_names)
        nominal = nominal_angles(model)
        self.cfg = np.array([nominal.get(j, 0.0) for j in self.joint_names])
        self._index = {j: i for i, j in enumerate(self.joint_names)}
        self.view.update_cfg(self.cfg)  # the full posture once; later only moving joints
        # frame handle + fixed origin of every revolute joint, for the cheap per-frame update
        self._joint_frames: dict[str, tuple[viser.FrameHandle, np.ndarray, np.ndarray]] = {}
        for joint, frame in zip(self.view._joint_map_values, self.view._joint_frames, strict=False):
            if joint.type in ("revolute", "continuous") and joint.mimic is None:
                origin = np.eye(4) if joint.origin is None else np.asarray(joint.origin)
                wxyz = vtf.SO3.from_matrix(origin[:3, :3]).wxyz
                axis = np.asarray(joint.axis if joint.axis is not None else (1, 0, 0), float)
                self._joint_frames[joint.name] = (frame, wxyz, axis / np.linalg.norm(axis))
        link_to_body = {link: body for body, link in self.spec.bodies.items()}
        self._body_of_mesh: dict[str, str] = {}
        for mesh in self.view._meshes:  # ViserUrdf keeps its mesh handles here
            parts = mesh.name.strip("/").split("/")
            body = next((link_to_body[p] for p in reversed(parts) if p in link_to_body), "pelvis")
            self._body_of_mesh[mesh.name] = body
            if on_body_click is not None:
                mesh.on_click(_click_handler(body, on_body_click))

    def body_of(self, mesh_name: str) -> str:
        """The push body a mesh belongs to."""
        return self._body_of_mesh.get(mesh_name, "pelvis")

    def update(
        self, base_position: np.ndarray, base_wxyz: np.ndarray, joints: dict[str, float]
    ) -> None:
        """Pose the robot: floating base (world) and joint angles by name (others stay nominal).

        Only the given joints' frames are rotated (R = R_origin R_axis(q)); ViserUrdf.update_cfg
        would recompute every frame of the tree (≈ 20 ms for Talos).
        """
        with self.server.atomic():
            self.root.position = np.asarray(base_position, dtype=float)
            self.root.wxyz = np.asarray(base_wxyz, dtype=float)
            for name, q in joints.items():
                i = self._index.get(name)
                if i is None or abs(self.cfg[i] - q) < 1e-5:
                    continue
                self.cfg[i] = q
                entry = self._joint_frames.get(name)
                if entry is not None:
                    frame, origin_wxyz, axis = entry
                    frame.wxyz = _quat_mul(origin_wxyz, _axis_angle(axis, q))

    def link_position(self, link: str) -> np.ndarray:
        """World position of a link's frame at the last pose."""
        self.urdf.update_cfg(self.cfg)
        T = self.urdf.get_transform(link, self.urdf.base_link)
        R = vtf.SO3(np.asarray(self.root.wxyz)).as_matrix()
        return np.asarray(self.root.position) + R @ T[:3, 3]

    def body_position(self, body: str) -> np.ndarray:
        """World position of a push body (torso, pelvis, thighs)."""
        return self.link_position(self.spec.bodies.get(body, self.urdf.base_link))

    def set_visible(self, visible: bool) -> None:
        self.root.visible = visible

    def remove(self) -> None:
        """Remove the robot (the root node takes every link frame and mesh with it)."""
        self.root.remove()
