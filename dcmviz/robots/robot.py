"""One robot, built once: :func:`load_robot` turns ``robot.model`` (a built-in name or the path of
a robot file) into a :class:`Robot` that carries everything any layer reads of it: the robot
file, the planning facts (:class:`~dcmviz.robots.spec.RobotSpec`), the Pinocchio model and
standing posture with the derived numbers (:class:`~dcmviz.robots.model.RobotModel`), the MuJoCo
model (:class:`~dcmviz.robots.mujoco_model.MujocoModel`, built on first use) and the visual model
(:class:`~dcmviz.robots.visual.RobotVisual`, meshes loaded on first use).

This is the only place a robot is looked up by name; the session loads it and hands it down.
"""

from __future__ import annotations

import functools
import math
import threading
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dcmviz.robots.feet import SIDES
from dcmviz.robots.file import (
    BUILTIN_ROBOTS,
    RobotFileError,
    parse_robot_file,
    resolve_robot_path,
)
from dcmviz.robots.model import RobotModel, build_from_file
from dcmviz.robots.spec import RobotSpec

if TYPE_CHECKING:
    from dcmviz.robots.crossover import CrossoverRegion
    from dcmviz.robots.mujoco_model import MujocoModel
    from dcmviz.robots.visual import RobotVisual

__all__ = ["Robot", "load_robot"]


class Robot:
    """A humanoid: its file, planning facts, Pinocchio model, MuJoCo model and visual model.

    Joint order: ``joint_names`` (the actuated joints) is Pinocchio's order; the MuJoCo model's
    motors follow it.
    """

    def __init__(self, name: str, rm: RobotModel) -> None:
        import pinocchio as pin

        self.name = name  # robot.model as given: a built-in name or a robot file's path
        self.model: RobotModel = rm
        self.file = rm.file
        self.spec: RobotSpec = rm.spec
        self.locked_joints: dict[str, float] = dict(rm.locked)  # joint -> locked angle, rad
        # whole-body QP gains the robot file sets ([controller]); the rest are Gains' defaults
        self.controller: dict[str, float | bool] = dict(rm.file.controller)
        self.pin_model = pm = pin.Model(rm.pin_model)  # own copy (armature set)
        # points along each leg's axis as frames (added before any data is made from the model):
        # the whole-body QP keeps the legs apart with them (dcmviz.sim.wbc.legs)
        from dcmviz.robots.crossover import leg_sample_points

        self.leg_frames: dict[str, tuple[int, ...]] = {}
        for side in SIDES:
            ids = []
            for k, (joint, point) in enumerate(leg_sample_points(rm, side)):
                jid = pm.getJointId(joint)
                frame = pin.Frame(
                    f"{side}_leg_point_{k}", jid, pm.getFrameId(joint, pin.JOINT),
                    pin.SE3(np.eye(3), point), pin.OP_FRAME,
                )  # fmt: skip
                ids.append(pm.addFrame(frame, False))
            self.leg_frames[side] = tuple(ids)
        self.joint_names: tuple[str, ...] = rm.joint_names
        self.nq, self.nv, self.nu = pm.nq, pm.nv, pm.nv - 6
        self.sole_frames = {s: pm.getFrameId(f"{s}_sole_link") for s in SIDES}
        self.torque_limit = np.array(pm.effortLimit[6:], dtype=float)
        self.armature = rm.armature
        self.damping = rm.damping
        self.foot_length, self.foot_width = rm.spec.foot_length_m, rm.spec.foot_width_m
        # nominal standing posture (solved by the loader): soles on z = 0
        self.q_nominal = q = rm.q_nominal.copy()
        data = pm.createData()
        pin.framesForwardKinematics(pm, data, q)
        self.mass = float(pin.computeTotalMass(pm))
        self.com_height = float(pin.centerOfMass(pm, data, q)[2])
        self.foot_spacing = float(
            data.oMf[self.sole_frames["left"]].translation[1]
            - data.oMf[self.sole_frames["right"]].translation[1]
        )
        # the base's orientation standing, relative to the feet's mean yaw: identity for a
        # robot whose base frame is upright and faces forward, a turn of π for one whose base
        # x axis points backwards (iCub); the whole-body QP holds the base at it
        yaws = [
            math.atan2(data.oMf[f].rotation[1, 0], data.oMf[f].rotation[0, 0])
            for f in self.sole_frames.values()
        ]
        feet_yaw = math.atan2(sum(map(math.sin, yaws)), sum(map(math.cos, yaws)))
        offset = pin.rpy.rpyToMatrix(0.0, 0.0, -feet_yaw) @ data.oMi[1].rotation
        angle = float(np.linalg.norm(pin.log3(offset)))
        self.base_offset: np.ndarray | None = None if angle < 1e-9 else offset
        self._lock = threading.Lock()
        self._mujoco: MujocoModel | None = None
        self._visual: RobotVisual | None = None
        self._crossover: CrossoverRegion | None = None
        self._crossover_reach: float | None = None
        self._levers: dict[str, float] = {}

    def __repr__(self) -> str:
        return f"Robot({self.name!r}, {self.mass:.2f} kg)"

    def __reduce__(self) -> tuple:
        """Pickled as its ``robot.model`` (a robot file's as an absolute path): unpickled, it is
        that process's own robot (:func:`load_robot`, built once per process and file version).
        A walker or a session state pickles with it, e.g. to continue a walk in a Ray worker."""
        model = self.name if self.name in BUILTIN_ROBOTS else resolve_robot_path(self.name)
        return (load_robot, (model,))

    @property
    def mujoco(self) -> MujocoModel:
        """The MuJoCo model (robot, floor, sole boxes, motors), built on first use."""
        with self._lock:
            if self._mujoco is None:
                from dcmviz.robots.mujoco_model import MujocoModel

                self._mujoco = MujocoModel(self.model)
            return self._mujoco

    @property
    def visual(self) -> RobotVisual:
        """The visual meshes and the kinematics that place them, loaded on first use (≈ 1 s)."""
        with self._lock:
            if self._visual is None:
                from dcmviz.robots.visual import RobotVisual

                self._visual = RobotVisual(self.name, self.model)
            return self._visual

    @property
    def crossover(self) -> CrossoverRegion:
        """Where the swinging foot can land across the stance foot (:mod:`.crossover`), derived
        from the legs' kinematics on first use (about a second)."""
        with self._lock:
            if self._crossover is None:
                from dcmviz.robots.crossover import derive_region

                self._crossover = derive_region(self.model)
            return self._crossover

    @property
    def crossover_reach(self) -> float:
        """How far (m) past the CoM a crossed sole can land, across (any base yaw;
        :func:`dcmviz.robots.crossover.reach_beyond_com`); 0 without a crossover region.
        Derived on first use (under a second on Talos)."""
        region = self.crossover
        with self._lock:
            if self._crossover_reach is None:
                from dcmviz.robots.crossover import reach_beyond_com

                self._crossover_reach = reach_beyond_com(self.model, "left", region.polygons)[0]
            return self._crossover_reach

    def push_lever_m(self, body: str) -> float:
        """Height (m) above the robot's CoM of the CoM of the body a push acts on (a push target
        of ``spec.bodies`` or a link name), standing in the nominal posture: a push there also
        brings a moment of this lever times its horizontal force about the CoM."""
        if body not in self._levers:
            link = self.spec.bodies.get(body, body)
            self._levers[body] = self.mujoco.body_above_com_m(link, self.q_nominal)
        return self._levers[body]


def load_robot(model: str) -> Robot:
    """The robot of ``robot.model`` (a built-in name or a robot file's path), built once per
    process and file version.  :class:`~dcmviz.robots.file.RobotFileError` (a ValueError) naming
    ``robot.model``, the file's key and what was expected otherwise."""
    try:
        path = resolve_robot_path(model)
        return _load(model, path, Path(path).stat().st_mtime_ns)
    except RobotFileError as err:
        if str(err).startswith("robot.model"):
            raise
        raise RobotFileError(f"robot.model = {model!r}: {err}") from None


@functools.lru_cache(maxsize=16)
def _load(model: str, path: str, mtime_ns: int) -> Robot:
    return Robot(model, build_from_file(parse_robot_file(path)))
