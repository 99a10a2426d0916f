"""The MuJoCo model of a robot, built from the same edited model text as its Pinocchio model, so the
kinematics and inertias agree by construction; the only colliding geoms are the two sole boxes
(added on the ``MjSpec``) and the floor.

Conventions: Pinocchio's configuration is ``q = [p_base, quat_xyzw, joints]`` and its free-flyer
velocity is expressed in the base frame; MuJoCo's is ``qpos = [p_base, quat_wxyz, joints]`` with
the free-joint linear velocity in the world frame and angular velocity in the base frame.
:meth:`MujocoModel.q_pin` / :meth:`~MujocoModel.v_pin` / :meth:`~MujocoModel.qpos_mj` /
:meth:`~MujocoModel.qvel_mj` convert.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin

from dcmviz import GRAVITY
from dcmviz.robots.feet import SIDES
from dcmviz.robots.model import RobotModel

SOLE_THICKNESS_M = 0.02  # the sole boxes' height (their top face is the sole frame)
# the legs as capsules along hip → knee → ankle → sole, radius × the sole's width: they collide
# with each other only (contype/conaffinity bits 2 and 4; the floor and soles use bit 1), so a
# crossing leg that touches the stance leg is a contact MuJoCo reports (and resolves)
LEG_RADIUS_PER_FOOT_WIDTH = 0.5
LEG_BITS = {"left": (2, 4), "right": (4, 2)}  # (contype, conaffinity)
MIN_SEGMENT_M = 0.01  # shorter leg segments (joints at one point) get no capsule
FRICTION = (1.0, 0.005, 0.0001)  # floor and soles: sliding, torsional, rolling


class MujocoModel:
    """A robot in MuJoCo: the robot, a flat floor, sole boxes and a motor per actuated joint.

    MuJoCo actuators are created in Pinocchio's joint order (``RobotModel.joint_names``), so
    ``data.ctrl = tau`` with ``tau`` in Pinocchio order.
    """

    def __init__(self, rm: RobotModel) -> None:
        text = rm.urdf_text
        if rm.is_mjcf:  # the edited MJCF: bodies, inertias, leg joints; no geometry
            spec = mujoco.MjSpec.from_string(text)
            spec.compiler.balanceinertia = True
            spec.option.gravity = [0.0, 0.0, -GRAVITY]  # Pinocchio's (the file may set its own)
        else:
            spec = mujoco.MjSpec.from_string(
                text.replace(
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
        floor.friction = list(FRICTION)
        floor.contype, floor.conaffinity = 1, 1
        spec.worldbody.add_light(pos=[0, 0, 3], dir=[0, 0, -1])
        fl, fw, fh = rm.spec.foot_length_m, rm.spec.foot_width_m, SOLE_THICKNESS_M
        for side in SIDES:
            body = spec.body(f"{side}_sole_link")
            geom = body.add_geom(
                name=f"{side}_sole", type=mujoco.mjtGeom.mjGEOM_BOX, size=[fl / 2, fw / 2, fh / 2]
            )
            geom.pos = [0, 0, fh / 2]
            geom.mass = 0.0
            geom.contype, geom.conaffinity = 1, 1
            geom.friction = list(FRICTION)
            geom.condim = 3
            body.add_site(name=f"{side}_sole", pos=[0, 0, 0], size=[0.01, 0.01, 0.01])
        torque_limit = np.array(rm.pin_model.effortLimit[6:], dtype=float)
        for jname, lim in zip(rm.joint_names, torque_limit, strict=True):
            joint = spec.joint(jname)
            joint.armature = rm.armature
            joint.damping = [rm.damping, 0.0, 0.0] if np.ndim(joint.damping) else rm.damping
            act = spec.add_actuator(name=jname, target=jname)
            act.trntype = mujoco.mjtTrn.mjTRN_JOINT
            act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
            act.gainprm[0] = 1.0
            act.biastype = mujoco.mjtBias.mjBIAS_NONE
            act.ctrllimited = True
            act.ctrlrange = [-lim, lim]
            # the joint's own clamp on actuator force (MuJoCo's URDF import sets it from
            # <limit effort>) equal to the same limit: one limit, whatever the file replaced
            joint.actfrclimited = mujoco.mjtLimited.mjLIMITED_TRUE
            joint.actfrcrange = [-lim, lim]
        self._add_leg_capsules(spec, rm, LEG_RADIUS_PER_FOOT_WIDTH * fw)
        self.model: mujoco.MjModel = spec.compile()
        # the uncompiled scene (robot + flat floor); a backend copies it to add terrain
        self.spec: mujoco.MjSpec = spec
        mm = self.model
        # the sole geoms were given zero mass; URDF inertials are used as they are
        self.qpos_adr = np.array([mm.jnt_qposadr[mm.joint(j).id] for j in rm.joint_names], int)
        self.dof_adr = np.array([mm.jnt_dofadr[mm.joint(j).id] for j in rm.joint_names], int)
        # the leg joints' block of qpos / qvel as a slice when it is contiguous (it is for Talos and
        # the G1): a slice copies without the index array
        self._qpos_index = _as_slice(self.qpos_adr)
        self._dof_index = _as_slice(self.dof_adr)
        self.nq_pin, self.nv_pin = rm.pin_model.nq, rm.pin_model.nv
        self.sole_sites = {s: mm.site(f"{s}_sole").id for s in SIDES}
        self.sole_geoms = {s: mm.geom(f"{s}_sole").id for s in SIDES}
        self.floor_geom = mm.geom("floor").id
        self.root_body_name = root_body.name
        self.leg_geoms = {
            side: np.array(
                [g for g in range(mm.ngeom) if mm.geom(g).name.startswith(f"{side}_leg_")]
            )
            for side in SIDES
        }
        # how deep the soles settle into MuJoCo's soft floor contact (set by the first backend)
        self.contact_sink_m: float | None = None

    # --- conversions -------------------------------------------------------------------------
    def q_pin(self, qpos: np.ndarray) -> np.ndarray:
        """Pinocchio q (quat xyzw) from MuJoCo qpos (quat wxyz)."""
        q = np.empty(self.nq_pin)
        q[:3] = qpos[:3]
        q[3:6] = qpos[4:7]
        q[6] = qpos[3]
        q[7:] = qpos[self._qpos_index]
        return q

    def qpos_mj(self, q: np.ndarray) -> np.ndarray:
        """MuJoCo qpos from Pinocchio q."""
        qpos = np.zeros(self.model.nq)
        qpos[:3] = q[:3]
        qpos[3] = q[6]
        qpos[4:7] = q[3:6]
        qpos[self.qpos_adr] = q[7:]
        return qpos

    def v_pin(self, qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
        """Pinocchio v (base twist in the base frame) from MuJoCo qvel (linear part in world)."""
        v = np.empty(self.nv_pin)
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, qpos[3:7])
        v[:3] = rot.reshape(3, 3).T @ qvel[:3]
        v[3:6] = qvel[3:6]
        v[6:] = qvel[self._dof_index]
        return v

    def qvel_mj(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """MuJoCo qvel from Pinocchio q, v."""
        qvel = np.zeros(self.model.nv)
        rot = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
        qvel[:3] = rot @ v[:3]
        qvel[3:6] = v[3:6]
        qvel[self.dof_adr] = v[6:]
        return qvel

    def leg_contacts(self, data: mujoco.MjData) -> int:
        """How many of ``data``'s contacts are between the left and the right leg."""
        if data.ncon == 0:
            return 0
        g1, g2 = data.contact.geom1[: data.ncon], data.contact.geom2[: data.ncon]
        left, right = self.leg_geoms["left"], self.leg_geoms["right"]
        return int(np.count_nonzero(
            (np.isin(g1, left) & np.isin(g2, right)) | (np.isin(g1, right) & np.isin(g2, left))
        ))  # fmt: skip

    @staticmethod
    def _add_leg_capsules(spec: mujoco.MjSpec, rm: RobotModel, radius: float) -> None:
        """Capsules along each leg's joint axes' anchors (hip to ankle) and on to the sole,
        each in the body of the joint it starts at (the next anchor is fixed in that body)."""
        model = spec.compile()
        data = mujoco.MjData(model)
        data.qpos[:] = 0.0
        data.qpos[3] = 1.0
        mujoco.mj_kinematics(model, data)
        for side in SIDES:
            ids = [model.joint(j).id for j in rm.legs[side]]
            points = [data.xanchor[j].copy() for j in ids]
            points.append(data.xpos[model.body(f"{side}_sole_link").id].copy())
            contype, conaffinity = LEG_BITS[side]
            for i, (a, b) in enumerate(zip(points[:-1], points[1:], strict=True)):
                if float(np.linalg.norm(b - a)) < MIN_SEGMENT_M:
                    continue
                body_id = int(model.jnt_bodyid[ids[i]])
                origin, rotation = data.xpos[body_id], data.xmat[body_id].reshape(3, 3)
                ends = [rotation.T @ (p - origin) for p in (a, b)]
                geom = spec.body(model.body(body_id).name).add_geom(
                    name=f"{side}_leg_{i}", type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                    fromto=[*ends[0], *ends[1]], size=[radius, 0.0, 0.0],
                )  # fmt: skip
                geom.mass = 0.0
                geom.contype, geom.conaffinity = contype, conaffinity
                geom.group = 3  # hidden in viewers that show groups 0-2

    def body_above_com_m(self, link: str, q: np.ndarray) -> float:
        """Height (m) of ``link``'s CoM above the robot's CoM at Pinocchio configuration ``q``
        (where MuJoCo applies a push on that body)."""
        data = mujoco.MjData(self.model)
        data.qpos[:] = self.qpos_mj(q)
        mujoco.mj_forward(self.model, data)
        bid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, link)
        if bid < 0:
            raise ValueError(f"body {link!r}: not a body of the model")
        return float(data.xipos[bid][2] - data.subtree_com[0][2])


def _as_slice(index: np.ndarray) -> slice | np.ndarray:
    """``index`` as a slice if it is a run of consecutive integers, else itself."""
    if len(index) and np.array_equal(index, np.arange(index[0], index[0] + len(index))):
        return slice(int(index[0]), int(index[0]) + len(index))
    return index
