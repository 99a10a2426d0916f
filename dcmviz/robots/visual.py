"""One visual model of each humanoid, shared by the dashboard (viser) and the recorder (rerun).

Built from the robot's full URDF through Pinocchio's visual :class:`pinocchio.GeometryModel`
(mesh paths resolve into example-robot-data's ``share/example-robot-data/robots``), or from its
MJCF's geoms (``pin.buildGeomFromMJCF``) for an MJCF robot.  A
:class:`RobotVisual` holds every visual mesh once (vertices in its own frame, colour, the link
it hangs on) and poses them from a :class:`~dcmviz.sim.backend.RobotPose`: floating base plus joint
angles by URDF joint name, any joint not given at the robot's nominal posture.

    visual = load_robot("talos").visual
    poses = visual.in_world(tick.pose)   # poses.position[i], poses.wxyz[i] place visual.meshes[i]

No viser and no rerun here: each shell draws the same meshes with its own public API.

The meshes are a display's level of detail: a robot whose visual meshes have more than
``DISPLAY_FACES`` triangles in all is decimated (quadric edge collapse, trimesh's
``simplify_quadric_decimation``), every mesh by the same ratio.  Headless Chromium draws a
triangle in about 1.3 µs in software WebGL, and every change in the page waits for the next
frame: Talos's 159 k triangles made a frame take ~250 ms longer than the rest of the scene
(bench/dashboard.py); at 24 k the robot costs ~60 ms and looks the same at dashboard distances
(each mesh keeps its extent within millimetres, tests/test_visual.py).  Collision geometry
(MuJoCo) and kinematics never use these meshes.
"""

from __future__ import annotations

import os
import threading
import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import trimesh
from scipy.spatial.transform import Rotation

from dcmviz.robots.file import example_robot_data_dir
from dcmviz.robots.heap import release_freed_memory
from dcmviz.robots.model import RobotModel
from dcmviz.robots.pose import RobotPose

DISPLAY_FACES = 24_000  # most triangles of one robot's visual meshes (a display's level of detail)
MIN_DECIMATED_FACES = 64  # a mesh is never decimated below this many triangles


@dataclass(frozen=True)
class VisualMesh:
    """One visual of a URDF link, in its own frame (the pose places that frame)."""

    name: str  # unique within the robot (Pinocchio's geometry name, e.g. "torso_2_link_0")
    link: str  # URDF link it is attached to
    vertices: np.ndarray  # (V, 3) float32, m, URDF scale applied
    faces: np.ndarray  # (F, 3) uint32
    normals: np.ndarray  # (V, 3) float32, unit vertex normals
    color: tuple[int, int, int, int]  # RGBA 0-255 from the URDF material
    ancestors: tuple[str, ...]  # frame names from ``link`` up to the root (for click → body)


@dataclass(frozen=True)
class MeshPoses:
    """Where each mesh of a :class:`RobotVisual` is: row i places ``meshes[i]``."""

    position: np.ndarray  # (n, 3) m
    wxyz: np.ndarray  # (n, 4) unit quaternions (w, x, y, z)


def _mesh_of(geometry: pin.GeometryObject) -> trimesh.Trimesh | None:
    """The triangles of a visual: its mesh file (scaled) or a primitive; None if unsupported."""
    shape = geometry.geometry
    kind = type(shape).__name__
    if kind.startswith("BVH") or kind == "Convex":
        mesh = trimesh.load(geometry.meshPath, force="mesh")
        mesh.apply_scale(np.asarray(geometry.meshScale, float))
        return mesh
    if kind == "Cylinder":
        return trimesh.creation.cylinder(radius=shape.radius, height=2.0 * shape.halfLength)
    if kind == "Box":
        return trimesh.creation.box(extents=2.0 * np.asarray(shape.halfSide, float))
    if kind == "Sphere":
        return trimesh.creation.icosphere(subdivisions=2, radius=shape.radius)
    return None


def _ancestors(model: pin.Model, frame_id: int) -> tuple[str, ...]:
    names = []
    while frame_id > 0:
        frame = model.frames[frame_id]
        names.append(frame.name)
        if frame.parentFrame == frame_id:
            break
        frame_id = frame.parentFrame
    return tuple(names)


def display_ratio(faces: list[int], budget: int | None = None) -> float:
    """The share of its triangles every mesh keeps so that all of them fit ``budget``
    (DISPLAY_FACES unless given; 1.0 when they already fit)."""
    budget = DISPLAY_FACES if budget is None else budget
    total = sum(faces)
    return 1.0 if total <= budget else budget / total


def decimated(mesh: trimesh.Trimesh, ratio: float) -> trimesh.Trimesh:
    """``mesh`` with about ``ratio`` of its triangles (never fewer than MIN_DECIMATED_FACES);
    the mesh itself when nothing is to remove."""
    target = max(MIN_DECIMATED_FACES, int(round(ratio * len(mesh.faces))))
    if ratio >= 1.0 or target >= len(mesh.faces):
        return mesh
    mesh = mesh.copy()
    mesh.merge_vertices()  # a mesh read as triangle soup (STL) collapses only once welded
    # aggression 3 of fast_simplification's 0 ("slow and good") to 10: at its default 7 the G1's
    # hands lost their fingers' shape (area -15 %), at 3 they keep it (-2 %)
    return mesh.simplify_quadric_decimation(face_count=target, aggression=3)


def _read_visuals(
    path: str,
) -> tuple[pin.Model, tuple[VisualMesh, ...], np.ndarray, np.ndarray]:
    """The model of a URDF or MJCF file, its visual meshes, the joint each hangs on and its
    (4, 4) placement in that joint's frame.  Pinocchio's geometry model (and every mesh it
    loaded) is dropped on return."""
    if path.lower().endswith((".xml", ".mjcf")):  # an MJCF model: its geoms, as Pinocchio
        model = pin.buildModelFromMJCFAndRootJoint(path, pin.JointModelFreeFlyer())
        geometry = pin.buildGeomFromMJCF(model, path, pin.GeometryType.VISUAL)
    else:
        share = os.path.dirname(
            os.path.dirname(example_robot_data_dir())
        )  # package://example-robot-data/…
        model = pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer())
        geometry = pin.buildGeomFromUrdf(model, path, pin.GeometryType.VISUAL, package_dirs=[share])
    read, unread = [], []
    for obj in geometry.geometryObjects:
        try:
            mesh = _mesh_of(obj)
        except Exception as err:  # noqa: BLE001 - any reader's failure: the robot is drawn without it
            unread.append(f"{os.path.basename(str(obj.meshPath))} ({type(err).__name__}: {err})")
            continue
        if mesh is None or len(mesh.faces) == 0:
            continue
        read.append((obj, mesh))
    ratio = display_ratio([len(mesh.faces) for _, mesh in read])
    meshes, joints, placements = [], [], []
    for obj, mesh in read:
        mesh = decimated(mesh, ratio)
        rgba = np.clip(np.asarray(obj.meshColor, float), 0.0, 1.0)
        meshes.append(
            VisualMesh(
                name=obj.name,
                link=model.frames[obj.parentFrame].name,
                vertices=np.asarray(mesh.vertices, np.float32),
                faces=np.asarray(mesh.faces, np.uint32),
                normals=np.asarray(mesh.vertex_normals, np.float32),
                color=tuple(int(round(255 * c)) for c in rgba),
                ancestors=_ancestors(model, obj.parentFrame),
            )
        )
        joints.append(int(obj.parentJoint))
        placements.append(np.array(obj.placement.homogeneous, float))
    if unread:  # named once, when the visual is built: the rest of the robot is still drawn
        warnings.warn(
            f"{path}: {len(unread)} of {len(geometry.geometryObjects)} visual meshes could not "
            f"be read and are not drawn: {'; '.join(unread[:3])}"
            + (" …" if len(unread) > 3 else ""),
            stacklevel=3,
        )
    placements = np.array(placements, float).reshape(-1, 4, 4)
    return model, tuple(meshes), np.array(joints, int), placements


class RobotVisual:
    """The visual meshes of one robot and the kinematics that place them."""

    def __init__(self, name: str, rm: RobotModel) -> None:
        """The visual model of robot ``name`` (``robot.model``) built as ``rm``."""
        self.model_name = name
        self.model, meshes, joints, placements = _read_visuals(rm.file.model_path)
        self.meshes: tuple[VisualMesh, ...] = meshes
        # what posing needs of each mesh: its joint and its placement in that joint's frame
        # (oMg = oMi[joint] · placement, as pin.updateGeometryPlacements).  The geometry model is
        # not kept: its BVH copy of every mesh (coal, native memory) holds ~50 MB for Talos and
        # ~200 MB for G1, and a visual lives as long as the process.
        self._joints, self._placements = joints, placements
        release_freed_memory()
        self._data = self.model.createData()
        self._lock = threading.Lock()  # the dashboard and a recorder may pose from two threads
        nominal = rm.nominal
        self.joint_names: tuple[str, ...] = tuple(
            self.model.names[j] for j in range(2, self.model.njoints)
        )  # 0 is the universe, 1 the floating base
        self._idx_q = np.array([self.model.joints[j].idx_q for j in range(2, self.model.njoints)])
        self._nq = np.array([self.model.joints[j].nq for j in range(2, self.model.njoints)])
        self._q0 = pin.neutral(self.model)
        self._set_joints(self._q0, {j: nominal.get(j, 0.0) for j in self.joint_names})

    # -- posing --------------------------------------------------------------------------------
    def in_world(self, pose: RobotPose) -> MeshPoses:
        """World pose of every mesh for a floating base and joint angles."""
        return self._poses(self._q(pose.joints, pose.base_position, pose.base_wxyz))

    def in_base(self, joints: Mapping[str, float]) -> MeshPoses:
        """Pose of every mesh relative to the floating base (base at the origin, unrotated)."""
        return self._poses(self._q(joints, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0])))

    def _q(self, joints: Mapping[str, float], position: np.ndarray, wxyz: np.ndarray) -> np.ndarray:
        """Pinocchio's configuration: [p, quat xyzw, joints]; joints not given stay nominal."""
        q = self._q0.copy()
        q[:3] = position
        w, x, y, z = np.asarray(wxyz, float) / np.linalg.norm(wxyz)
        q[3:7] = (x, y, z, w)
        self._set_joints(q, joints)
        return q

    def _set_joints(self, q: np.ndarray, joints: Mapping[str, float]) -> None:
        for name, idx, nq in zip(self.joint_names, self._idx_q, self._nq, strict=True):
            angle = joints.get(name)
            if angle is None:
                continue
            if nq == 1:
                q[idx] = angle
            elif nq == 2:  # continuous joint: (cos, sin)
                q[idx : idx + 2] = (np.cos(angle), np.sin(angle))

    def _poses(self, q: np.ndarray) -> MeshPoses:
        with self._lock:
            pin.forwardKinematics(self.model, self._data, q)
            joints = self._data.oMi
            T = np.array([joints[int(j)].homogeneous for j in self._joints]).reshape(-1, 4, 4)
        T = T @ self._placements  # oMg = oMi[joint] · placement
        xyzw = Rotation.from_matrix(T[:, :3, :3]).as_quat()
        return MeshPoses(position=T[:, :3, 3].copy(), wxyz=np.roll(xyzw, 1, axis=1))
