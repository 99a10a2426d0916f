"""A robot file built into a MuJoCo and a Pinocchio model of the same bodies.

:mod:`dcmviz.robots.model` reads the robot file (``docs/robots.md``), edits the URDF (upper body
locked at the posture, ``left_sole_link``/``right_sole_link`` added at the sole centres, geometry
removed), builds the Pinocchio model and solves the nominal standing posture.  Here MuJoCo is
built from the *same* edited URDF text, so the kinematics and inertias agree by construction;
the only colliding geoms are the two sole boxes (added on the ``MjSpec``) and the floor.

Conventions: Pinocchio's configuration is ``q = [p_base, quat_xyzw, joints]`` and its free-flyer
velocity is expressed in the base frame; MuJoCo's is ``qpos = [p_base, quat_wxyz, joints]`` with
the free-joint linear velocity in the world frame and angular velocity in the base frame.
:meth:`Robot.q_pin` / :meth:`Robot.v_pin` / :meth:`Robot.qpos_mj` / :meth:`Robot.qvel_mj` convert.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

from dcmviz import GRAVITY
from dcmviz.robots import RobotSpec
from dcmviz.robots.file import example_robot_data_dir, resolve_robot_path
from dcmviz.robots.model import SIDES, RobotModel, build_model, solve_posture

__all__ = ["SIDES", "Robot", "RobotSource", "load_robot", "robot_source", "robots_dir"]


def robots_dir() -> str:
    """Directory of ``example-robot-data``'s ``robots`` (found under the cmeel prefix)."""
    return example_robot_data_dir()


@dataclass(frozen=True)
class RobotSource:
    """Where a robot comes from, as read from its robot file (for the visual model)."""

    urdf: str  # absolute path of the full URDF (or MJCF: see RobotModel.is_mjcf)
    legs: tuple[str, ...]  # actuated joints, left leg then right leg (hip to ankle), then kept
    nominal: dict[str, float]  # nominal angle of every joint the posture sets (locked or not), rad
    sole_parent: dict[str, str | None]  # side -> link a sole link was added under (None: URDF's)
    sole_offset: dict[str, tuple[float, float, float]]  # sole origin in the parent link, m
    armature: float  # kg m², reflected rotor inertia of each actuated joint
    damping: float  # N m s/rad, viscous joint damping


def robot_source(name: str) -> RobotSource:
    """Where robot ``name`` (built-in name or robot file path) comes from."""
    rm = build_model(name)
    return RobotSource(
        urdf=rm.file.model_path,
        legs=(*rm.legs["left"], *rm.legs["right"], *rm.file.joints.keep),
        nominal=dict(rm.nominal),
        sole_parent=dict(rm.sole_parent),
        sole_offset=dict(rm.sole_offset),
        armature=rm.armature,
        damping=rm.damping,
    )


def _center_com_over_soles(
    model: pin.Model, q: np.ndarray, sole_frames: dict[str, int], iterations: int = 30
) -> np.ndarray:
    """The posture closest to ``q`` with the CoM above the middle of the soles (x, y)
    (:func:`dcmviz.robots.model.solve_posture` without a height)."""
    return solve_posture(model, q, sole_frames, None, iterations)[0]


class Robot:
    """A humanoid as a MuJoCo model and a Pinocchio model of the same bodies, plus name maps.

    Joint order: ``joint_names`` (the actuated leg joints) is Pinocchio's order; MuJoCo actuators
    are created in that order, so ``data.ctrl = tau`` with ``tau`` in Pinocchio order.
    """

    def __init__(self, name: str) -> None:
        rm: RobotModel = build_model(name)  # RobotFileError naming the key of a bad file
        self.model_file: RobotModel = rm
        self.spec: RobotSpec = rm.spec
        self.name = name
        self.locked_joints: dict[str, float] = dict(rm.locked)  # joint -> locked angle, rad
        urdf = rm.urdf_text
        self.urdf_text = urdf
        # whole-body QP gains the robot file sets ([controller]); the rest are Gains' defaults
        self.controller: dict[str, float | bool] = dict(rm.file.controller)

        # --- Pinocchio ---------------------------------------------------------------------
        self.pin_model: pin.Model = pin.Model(rm.pin_model)  # own copy (armature set)
        pm = self.pin_model
        self.joint_names: tuple[str, ...] = rm.joint_names
        self.nq, self.nv, self.nu = pm.nq, pm.nv, pm.nv - 6
        self.sole_frames = {s: pm.getFrameId(f"{s}_sole_link") for s in SIDES}
        self.torque_limit = np.array(pm.effortLimit[6:], dtype=float)
        self.armature = rm.armature
        self.damping = rm.damping

        # --- MuJoCo --------------------------------------------------------------------------
        if rm.is_mjcf:  # the edited MJCF: bodies, inertias, leg joints; no geometry
            spec = mujoco.MjSpec.from_string(urdf)
            spec.compiler.balanceinertia = True
            spec.option.gravity = [0.0, 0.0, -GRAVITY]  # Pinocchio's (the file may set its own)
        else:
            spec = mujoco.MjSpec.from_string(
                urdf.replace(
                    "</robot>",
                    '<mujoco><compiler discardvisual="true" balanceinertia="true" '
                    'strippath="false" fusestatic="false"/></mujoco></robot>',
                )
            )
        spec.option.timestep = 0.001
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        spec.option.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL
        root_body = spec.worldbody.first_body()
        root_body.add_freejoint(name="root")
        floor = spec.worldbody.add_geom(
            name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05]
        )
        floor.friction = [1.0, 0.005, 0.0001]
        floor.contype, floor.conaffinity = 1, 1
        spec.worldbody.add_light(pos=[0, 0, 3], dir=[0, 0, -1])
        fl, fw, fh = self.spec.foot_length_m, self.spec.foot_width_m, 0.02
        for side in SIDES:
            body = spec.body(f"{side}_sole_link")
            geom = body.add_geom(
                name=f"{side}_sole", type=mujoco.mjtGeom.mjGEOM_BOX, size=[fl / 2, fw / 2, fh / 2]
            )
            geom.pos = [0, 0, fh / 2]
            geom.mass = 0.0
            geom.contype, geom.conaffinity = 1, 1
            geom.friction = [1.0, 0.005, 0.0001]
            geom.condim = 3
            body.add_site(name=f"{side}_sole", pos=[0, 0, 0], size=[0.01, 0.01, 0.01])
        for jname, lim in zip(self.joint_names, self.torque_limit, strict=True):
            joint = spec.joint(jname)
            joint.armature = self.armature
            joint.damping = [self.damping, 0.0, 0.0] if np.ndim(joint.damping) else self.damping
            act = spec.add_actuator(name=jname, target=jname)
            act.trntype = mujoco.mjtTrn.mjTRN_JOINT
            act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
            act.gainprm[0] = 1.0
            act.biastype = mujoco.mjtBias.mjBIAS_NONE
            act.ctrllimited = True
            act.ctrlrange = [-lim, lim]
        self.mj_model: mujoco.MjModel = spec.compile()
        # the uncompiled scene (robot + flat floor); a backend copies it to add terrain
        self.mj_spec: mujoco.MjSpec = spec
        mm = self.mj_model
        # the sole geoms were given zero mass; URDF inertials are used as they are
        self.qpos_adr = np.array(
            [mm.jnt_qposadr[mm.joint(j).id] for j in self.joint_names], dtype=int
        )
        self.dof_adr = np.array(
            [mm.jnt_dofadr[mm.joint(j).id] for j in self.joint_names], dtype=int
        )
        # the leg joints' block of qpos / qvel as a slice when it is contiguous (it is for Talos and
        # the G1): a slice copies without the index array
        self._qpos_index = _as_slice(self.qpos_adr)
        self._dof_index = _as_slice(self.dof_adr)
        self.sole_sites = {s: mm.site(f"{s}_sole").id for s in SIDES}
        self.sole_geoms = {s: mm.geom(f"{s}_sole").id for s in SIDES}
        self.floor_geom = mm.geom("floor").id
        self.root_body_name = root_body.name

        # --- nominal standing posture (solved by the robot file's loader): soles on z = 0 ------
        self.q_nominal = q = rm.q_nominal.copy()
        data = pm.createData()
        pin.framesForwardKinematics(pm, data, q)
        self.mass = float(pin.computeTotalMass(pm))
        self.com_height = float(pin.centerOfMass(pm, data, q)[2])
        self.foot_spacing = float(
            data.oMf[self.sole_frames["left"]].translation[1]
            - data.oMf[self.sole_frames["right"]].translation[1]
        )
        self.foot_length, self.foot_width = fl, fw
        # how deep the soles settle into MuJoCo's soft floor contact (set by the first backend)
        self.contact_sink_m: float | None = None

    # --- conversions -------------------------------------------------------------------------
    def q_pin(self, qpos: np.ndarray) -> np.ndarray:
        """Pinocchio q (quat xyzw) from MuJoCo qpos (quat wxyz)."""
        q = np.empty(self.nq)
        q[:3] = qpos[:3]
        q[3:6] = qpos[4:7]
        q[6] = qpos[3]
        q[7:] = qpos[self._qpos_index]
        return q

    def qpos_mj(self, q: np.ndarray) -> np.ndarray:
        """MuJoCo qpos from Pinocchio q."""
        qpos = np.zeros(self.mj_model.nq)
        qpos[:3] = q[:3]
        qpos[3] = q[6]
        qpos[4:7] = q[3:6]
        qpos[self.qpos_adr] = q[7:]
        return qpos

    def v_pin(self, qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
        """Pinocchio v (base twist in the base frame) from MuJoCo qvel (linear part in world)."""
        v = np.empty(self.nv)
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, qpos[3:7])
        v[:3] = rot.reshape(3, 3).T @ qvel[:3]
        v[3:6] = qvel[3:6]
        v[6:] = qvel[self._dof_index]
        return v

    def qvel_mj(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """MuJoCo qvel from Pinocchio q, v."""
        qvel = np.zeros(self.mj_model.nv)
        rot = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        qvel[:3] = rot @ v[:3]
        qvel[3:6] = v[3:6]
        qvel[self.dof_adr] = v[6:]
        return qvel


def _as_slice(index: np.ndarray) -> slice | np.ndarray:
    """``index`` as a slice if it is a run of consecutive integers, else itself."""
    if len(index) and np.array_equal(index, np.arange(index[0], index[0] + len(index))):
        return slice(int(index[0]), int(index[0]) + len(index))
    return index


def load_robot(name: str) -> Robot:
    """The robot of ``robot.model`` (a built-in name or a robot file's path), built once per
    process and file version; ValueError (RobotFileError) naming the key otherwise."""
    path = resolve_robot_path(name)
    return _load_robot(name, path, Path(path).stat().st_mtime_ns)


@functools.lru_cache(maxsize=16)
def _load_robot(name: str, path: str, mtime_ns: int) -> Robot:
    return Robot(name)
