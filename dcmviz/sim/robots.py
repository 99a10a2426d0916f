"""Talos and G1 built once from ``example-robot-data`` URDFs into a MuJoCo and a Pinocchio model.

Both models are built from the *same* edited URDF text, so their kinematics and inertias agree
by construction:

* the upper body (torso/waist, arms, head, grippers) is locked at the nominal posture: each
  locked revolute joint becomes a fixed joint whose origin absorbs ``R_axis(q_nominal)``;
* every robot gets ``left_sole_link``/``right_sole_link`` at the centre of its support rectangle
  (Talos has them; for the G1 they are added below ``*_ankle_roll_link``);
* visuals and collision meshes are dropped; the only colliding geoms are the two sole boxes
  (MuJoCo, added on the ``MjSpec``) and the floor.

Conventions: Pinocchio's configuration is ``q = [p_base, quat_xyzw, joints]`` and its free-flyer
velocity is expressed in the base frame; MuJoCo's is ``qpos = [p_base, quat_wxyz, joints]`` with
the free-joint linear velocity in the world frame and angular velocity in the base frame.
:meth:`Robot.q_pin` / :meth:`Robot.v_pin` / :meth:`Robot.qpos_mj` / :meth:`Robot.qvel_mj` convert.
"""

from __future__ import annotations

import functools
import os
import site
import sysconfig
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from dcmviz.robots import RobotSpec, get_spec

SIDES = ("left", "right")


def robots_dir() -> str:
    """Directory of ``example-robot-data``'s ``robots`` (found under the cmeel prefix)."""
    candidates = [sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]]
    try:
        candidates += site.getsitepackages()
    except AttributeError:  # pragma: no cover - virtualenv without getsitepackages
        pass
    candidates.append(site.getusersitepackages())
    for base in candidates:
        path = os.path.join(base, "cmeel.prefix", "share", "example-robot-data", "robots")
        if os.path.isdir(path):
            return path
    raise FileNotFoundError(
        "example-robot-data not found under any site-packages/cmeel.prefix; "
        "install it with `pip install example-robot-data`"
    )


@dataclass(frozen=True)
class RobotSource:
    urdf: str  # path relative to robots_dir()
    legs: tuple[str, ...]  # actuated joints, left leg then right leg, hip to ankle
    nominal: dict[str, float]  # nominal angle of every non-zero joint (locked or not), rad
    sole_parent: dict[str, str] | None  # side -> link to add a sole under (None: URDF has soles)
    sole_offset: tuple[float, float, float]  # sole origin in the parent link, m
    armature: float  # kg m², reflected rotor inertia of each leg joint
    damping: float  # N m s/rad, viscous joint damping


def _talos_nominal() -> dict[str, float]:
    root = robots_dir()
    srdf = ET.parse(os.path.join(root, "talos_data", "srdf", "talos.srdf")).getroot()
    for state in srdf.iter("group_state"):
        if state.get("name") == "half_sitting":
            return {
                j.get("name"): float(j.get("value"))
                for j in state.iter("joint")
                if j.get("name") != "root_joint"
            }
    raise ValueError("talos.srdf has no half_sitting state")  # pragma: no cover


_LEG_SUFFIX_G1 = ("hip_pitch", "hip_roll", "hip_yaw", "knee", "ankle_pitch", "ankle_roll")


def robot_source(name: str) -> RobotSource:
    """Where a robot comes from: its URDF, leg joints, nominal posture, sole placement."""
    if name == "talos":
        return RobotSource(
            urdf="talos_data/robots/talos_reduced.urdf",
            legs=tuple(f"leg_{s}_{i}_joint" for s in SIDES for i in range(1, 7)),
            nominal=_talos_nominal(),
            sole_parent=None,
            sole_offset=(0.0, 0.0, 0.0),
            armature=0.05,
            damping=0.2,
        )
    if name == "g1":
        nominal = {}
        for s in SIDES:
            nominal[f"{s}_hip_pitch_joint"] = -0.312
            nominal[f"{s}_knee_joint"] = 0.669
            nominal[f"{s}_ankle_pitch_joint"] = -0.363
            nominal[f"{s}_elbow_joint"] = 0.6
            nominal[f"{s}_shoulder_roll_joint"] = 0.2 if s == "left" else -0.2
        return RobotSource(
            urdf="g1_description/urdf/g1_29dof_rev_1_0.urdf",
            legs=tuple(f"{s}_{j}_joint" for s in SIDES for j in _LEG_SUFFIX_G1),
            nominal=nominal,
            sole_parent={s: f"{s}_ankle_roll_link" for s in SIDES},
            # centre of the 4 contact spheres (x -0.05..0.12, z -0.03 - r 0.005)
            sole_offset=(0.035, 0.0, -0.035),
            armature=0.01,
            damping=0.05,
        )
    raise ValueError(f"robot {name!r}: unknown robot; allowed: talos, g1")


def _axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues: R = I + sin θ [a]× + (1 - cos θ) [a]×²."""
    a = axis / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _rpy_to_matrix(rpy: np.ndarray) -> np.ndarray:
    return pin.rpy.rpyToMatrix(*rpy)


def _edit_urdf(src: RobotSource, locked: dict[str, float] | None = None) -> str:
    """The URDF text with the upper body locked, soles added and geometry removed.

    ``locked`` (if given) receives the name and angle (rad) of every joint that was locked."""
    tree = ET.parse(os.path.join(robots_dir(), src.urdf))
    root = tree.getroot()
    for link in root.findall("link"):
        for tag in ("visual", "collision"):
            for el in link.findall(tag):
                link.remove(el)
    for tag in ("transmission", "gazebo", "material"):
        for el in root.findall(tag):
            root.remove(el)
    for joint in root.findall("joint"):
        jtype = joint.get("type")
        name = joint.get("name")
        if jtype in ("revolute", "continuous", "prismatic") and name not in src.legs:
            angle = src.nominal.get(name, 0.0)
            if locked is not None:
                locked[name] = angle
            origin = joint.find("origin")
            if origin is None:
                origin = ET.SubElement(joint, "origin", xyz="0 0 0", rpy="0 0 0")
            rpy = np.array([float(v) for v in origin.get("rpy", "0 0 0").split()])
            axis_el = joint.find("axis")
            axis = np.array(
                [float(v) for v in (axis_el.get("xyz") if axis_el is not None else "1 0 0").split()]
            )
            if jtype == "prismatic":
                raise ValueError(f"cannot lock prismatic joint {name}")  # pragma: no cover
            rot = _rpy_to_matrix(rpy) @ _axis_rotation(axis, angle)
            origin.set("rpy", " ".join(f"{v:.17g}" for v in pin.rpy.matrixToRpy(rot)))
            joint.set("type", "fixed")
            for tag in ("mimic", "limit", "axis", "dynamics", "safety_controller"):
                for el in joint.findall(tag):
                    joint.remove(el)
    if src.sole_parent is not None:
        for side, parent in src.sole_parent.items():
            link = ET.SubElement(root, "link", name=f"{side}_sole_link")
            inertial = ET.SubElement(link, "inertial")
            ET.SubElement(inertial, "origin", xyz="0 0 0", rpy="0 0 0")
            ET.SubElement(inertial, "mass", value="1e-4")
            ET.SubElement(
                inertial, "inertia", ixx="1e-8", ixy="0", ixz="0", iyy="1e-8", iyz="0", izz="1e-8"
            )
            joint = ET.SubElement(root, "joint", name=f"{side}_sole_fix_joint", type="fixed")
            ET.SubElement(joint, "parent", link=parent)
            ET.SubElement(joint, "child", link=f"{side}_sole_link")
            ET.SubElement(
                joint, "origin", xyz=" ".join(str(v) for v in src.sole_offset), rpy="0 0 0"
            )
    return ET.tostring(root, encoding="unicode")


def _center_com_over_soles(
    model: pin.Model, q: np.ndarray, sole_frames: dict[str, int], iterations: int = 30
) -> np.ndarray:
    """The posture closest to ``q`` with the CoM above the middle of the soles (x, y) and the
    soles where they are (flat, on the floor): Gauss-Newton on the legs and base position,
    e = [log6(oMf_d⁻¹ oMf) per sole; c_xy - s_xy], Δq = -J⁺ e (base orientation kept)."""
    data = model.createData()
    q = q.copy()
    pin.framesForwardKinematics(model, data, q)
    targets = {s: data.oMf[f].copy() for s, f in sole_frames.items()}
    middle = np.mean([t.translation[:2] for t in targets.values()], axis=0)
    cols = np.r_[0:3, 6 : model.nv]  # base translation and joints
    for _ in range(iterations):
        pin.framesForwardKinematics(model, data, q)
        pin.computeJointJacobians(model, data, q)
        com = pin.centerOfMass(model, data, q)
        errors, rows = [], []
        for s, f in sole_frames.items():
            errors.append(pin.log6(targets[s].actInv(data.oMf[f])).vector)
            rows.append(pin.getFrameJacobian(model, data, f, pin.LOCAL))
        errors.append(com[:2] - middle)
        rows.append(pin.jacobianCenterOfMass(model, data, q)[:2])
        e, J = np.concatenate(errors), np.vstack(rows)[:, cols]
        if np.linalg.norm(e) < 1e-10:
            break
        dv = np.zeros(model.nv)
        dv[cols] = -np.linalg.lstsq(J, e, rcond=None)[0]
        q = pin.integrate(model, q, dv)
    return q


class Robot:
    """A humanoid as a MuJoCo model and a Pinocchio model of the same bodies, plus name maps.

    Joint order: ``joint_names`` (the actuated leg joints) is Pinocchio's order; MuJoCo actuators
    are created in that order, so ``data.ctrl = tau`` with ``tau`` in Pinocchio order.
    """

    def __init__(self, name: str) -> None:
        self.spec: RobotSpec = get_spec(name)
        self.name = name
        src = robot_source(name)
        self.locked_joints: dict[str, float] = {}  # upper-body joint -> locked angle, rad
        urdf = _edit_urdf(src, self.locked_joints)
        self.urdf_text = urdf

        # --- Pinocchio ---------------------------------------------------------------------
        self.pin_model: pin.Model = pin.buildModelFromXML(urdf, pin.JointModelFreeFlyer())
        pm = self.pin_model
        self.joint_names: tuple[str, ...] = tuple(pm.names[2:])
        if set(self.joint_names) != set(src.legs):
            raise RuntimeError(f"unexpected actuated joints {self.joint_names}")
        self.nq, self.nv, self.nu = pm.nq, pm.nv, pm.nv - 6
        self.sole_frames = {s: pm.getFrameId(f"{s}_sole_link") for s in SIDES}
        self.torque_limit = np.array(pm.effortLimit[6:], dtype=float)
        pm.armature[6:] = src.armature
        self.armature = src.armature
        self.damping = src.damping

        # --- MuJoCo --------------------------------------------------------------------------
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
            joint.armature = src.armature
            joint.damping = [src.damping, 0.0, 0.0] if np.ndim(joint.damping) else src.damping
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

        # --- nominal standing posture: soles on z = 0 ---------------------------------------
        q = pin.neutral(pm)
        for i, j in enumerate(self.joint_names):
            q[7 + i] = src.nominal.get(j, 0.0)
        data = pm.createData()
        pin.framesForwardKinematics(pm, data, q)
        sole_z = np.mean([data.oMf[f].translation[2] for f in self.sole_frames.values()])
        sole_x = np.mean([data.oMf[f].translation[0] for f in self.sole_frames.values()])
        q[0] -= sole_x  # sole centres at x = 0
        q[2] = -sole_z  # soles on the floor
        self.q_nominal = q = _center_com_over_soles(pm, q, self.sole_frames)
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


@functools.cache
def load_robot(name: str) -> Robot:
    """The robot ``name`` ("talos" or "g1"), built once per process; ValueError otherwise."""
    get_spec(name)  # raises ValueError naming the allowed robots
    return Robot(name)
