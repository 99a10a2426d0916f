"""A robot file → an edited URDF, a Pinocchio model, the nominal standing posture and every number
that can be derived from them (mass, CoM heights, reach, limits, b's range).

The URDF is edited once and both simulators are built from that text
(:mod:`dcmviz.sim.robots` adds MuJoCo):

* the leg joints are found from the feet: the movable joints on the chain from the root link to
  each foot's link; ``joints.keep`` adds actuated joints, every other movable joint is locked at
  the posture (it becomes a fixed joint whose origin absorbs ``R_axis(q)``);
* every foot gets a ``left_sole_link``/``right_sole_link`` at the centre of its sole rectangle
  (``feet.<side>.link`` + ``offset``; a URDF link of that name with zero offset is used as is);
* visuals and collision meshes are dropped.

Everything here raises :class:`~dcmviz.robots.file.RobotFileError` naming the key of the robot
file and what was expected; nothing is cached before the whole check has passed.
"""

from __future__ import annotations

import functools
import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dcmviz import GRAVITY
from dcmviz.robots.file import RobotFile, parse_robot_file, resolve_robot_path
from dcmviz.robots.file import file_error as _err
from dcmviz.robots.legs import find_legs
from dcmviz.robots.legs import suggest as _suggest
from dcmviz.robots.spec import RobotSpec

SIDES = ("left", "right")
MOVABLE = ("revolute", "continuous", "prismatic")

# rules that derive the walking numbers (docs/robots.md, "Derived numbers")
JOINT_MARGIN_RAD = 0.05  # a walkable posture keeps each leg joint this far inside its range
TORQUE_FRACTION = 0.9  # … and holds the whole weight on one leg with ≤ this fraction of each limit
LOWEST_HEIGHT_FRACTION = 0.8  # … with the CoM at least this fraction of the straight-leg height
STRAIGHT_MARGIN = 0.04  # highest CoM: straight-leg height − this × leg length (knees still bent)
STEP_LENGTH_PER_LEG = 0.55  # max |Δx| of a step per m of hip → sole (Talos 0.45 m / 0.81 m)
STEP_WIDTH_PER_LEG = 0.62  # max distance between the feet per m of leg length
STEP_HEIGHT_PER_LEG = 0.18  # max |Δz| of a step per m of leg length
FEET_GAP_M = 0.01  # min distance between the soles' inner edges
FASTEST_SWING_S = 0.5  # the swing foot crosses 2 × max step length in this time at most
REACH_FRACTION = 0.7  # at touchdown the front foot is this fraction of the step ahead of the CoM
TURN_PER_HIP_YAW = 0.5  # max turn per step per rad of the hip yaw's smaller side of its range
MAX_TURN_RAD = 0.5  # the preset schema's bound on gait.turn
# actuator defaults per kg of robot (Talos: 0.05 kg m², 0.2 N m s/rad at 90.27 kg)
ARMATURE_PER_KG = 0.05 / 90.27
DAMPING_PER_KG = 0.2 / 90.27


@dataclass(frozen=True)
class LegLimits:
    """Limits of one leg joint from the URDF."""

    lower_rad: float
    upper_rad: float
    torque_nm: float
    velocity_rad_s: float


@dataclass(frozen=True)
class Derived:
    """Numbers derived from the model (before any ``[walking]`` pin replaces them)."""

    mass_kg: float
    com_height_m: float  # CoM above the soles in the nominal posture
    foot_spacing_m: float  # lateral distance of the sole centres in the nominal posture
    hip_sole_m: float  # first leg joint → sole centre with the leg joints at zero (reach scale)
    hip_below_com_m: float  # hip roll joint below the CoM, standing
    ankle_above_sole_m: float  # ankle pitch joint above the sole, standing
    leg_length_m: float  # hip–ankle distance standing at max_com_height_m (dcmviz.gait.height)
    straight_com_height_m: float  # CoM above the soles with the leg joints at zero
    min_com_height_m: float
    max_com_height_m: float
    min_height_reason: str  # what stops the squat
    stride_reason: str  # what stops the longest step
    max_step_length_m: float
    max_step_width_m: float
    min_step_width_m: float
    max_step_height_m: float
    max_swing_speed_m_s: float
    max_turn_rad: float  # per generated step, from the hip yaw joints' ranges
    hip_yaw: tuple[str, ...]  # the leg joints with a vertical axis standing


@dataclass(frozen=True, eq=False)
class RobotModel:
    """A robot file built into a Pinocchio model with its nominal standing posture."""

    file: RobotFile
    # the edited model text, URDF or MJCF (``is_mjcf``): upper body locked, soles added, no geometry
    urdf_text: str
    pin_model: object  # pinocchio.Model (free flyer), armature set
    joint_names: tuple[str, ...]  # actuated joints, Pinocchio's order
    legs: dict[str, tuple[str, ...]]  # side -> leg joints, hip to ankle
    locked: dict[str, float]  # locked joint -> angle, rad
    nominal: dict[str, float]  # posture of every joint (locked or not) before solving, rad
    sole_parent: dict[str, str | None]  # side -> link a sole link was added under (None: URDF's)
    sole_offset: dict[str, tuple[float, float, float]]
    q_nominal: np.ndarray  # Pinocchio q of the standing posture (soles on z = 0, centred at x = 0)
    limits: dict[str, LegLimits]  # per actuated joint
    armature: float
    damping: float
    derived: Derived
    spec: object = field(repr=False)  # dcmviz.robots.spec.RobotSpec (pins applied)

    @property
    def is_mjcf(self) -> bool:
        """True if the robot file names an MJCF model (``urdf_text`` is then MJCF)."""
        return bool(self.file.mjcf_path)


def srdf_state(rf: RobotFile) -> dict[str, float]:
    """Joint angles of ``model.reference_posture`` in ``model.srdf`` (empty without one)."""
    if rf.srdf_path is None or rf.model.reference_posture is None:
        return {}
    try:
        root = ET.parse(rf.srdf_path).getroot()
    except ET.ParseError as err:
        raise _err(rf, f"model.srdf = {rf.model.srdf!r}: not valid XML ({err})") from None
    states = [s.get("name") for s in root.iter("group_state")]
    for state in root.iter("group_state"):
        if state.get("name") == rf.model.reference_posture:
            return {
                j.get("name"): float(j.get("value"))
                for j in state.iter("joint")
                if j.get("name") != "root_joint" and j.get("value") is not None
            }
    raise _err(
        rf,
        f"model.reference_posture = {rf.model.reference_posture!r}: no such <group_state> in "
        f"{os.path.basename(rf.srdf_path)}; expected one of {', '.join(map(str, states)) or '(none)'}",
    )


def _axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues: R = I + sin θ [a]× + (1 - cos θ) [a]×²."""
    a = axis / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _parse_urdf(rf: RobotFile) -> ET.Element:
    try:
        return ET.parse(rf.urdf_path).getroot()
    except ET.ParseError as err:
        raise _err(rf, f"model.urdf = {rf.model.urdf!r}: the URDF does not load: {err}") from None


def _legs(rf: RobotFile, root: ET.Element) -> dict[str, tuple[str, ...]]:
    """The movable joints from the root link to each foot's link, hip to ankle."""
    links = [link.get("name") for link in root.findall("link")]
    parent_joint: dict[str, ET.Element] = {}
    for joint in root.findall("joint"):
        child = joint.find("child")
        if child is not None:
            parent_joint[child.get("link")] = joint
    roots = [n for n in links if n not in parent_joint]

    def chain_of(foot: str) -> Iterator[tuple[str, str]]:
        link = foot
        while link in parent_joint:
            joint = parent_joint[link]
            if joint.get("type") in MOVABLE:
                yield joint.get("name"), joint.get("type")
            link = joint.find("parent").get("link")

    return find_legs(
        rf, links, "link", os.path.basename(rf.urdf_path), chain_of, "revolute",
        f"link {(roots or ['?'])[0]!r}",
    )  # fmt: skip


def _edit_urdf(
    rf: RobotFile,
    root: ET.Element,
    actuated: set[str],
    nominal: dict[str, float],
    locked: dict[str, float],
) -> tuple[str, dict[str, str | None]]:
    """The URDF text with the non-actuated joints locked, soles added and geometry removed;
    ``locked`` receives every locked joint and its angle (rad).  Returns the text and, per side,
    the link a sole link was added under (None when the URDF's ``<side>_sole_link`` is used)."""
    import pinocchio as pin

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
        if jtype in MOVABLE and name not in actuated:
            if jtype == "prismatic":
                raise _err(rf, f"joints: cannot lock prismatic joint {name!r}")
            angle = nominal.get(name, 0.0)
            locked[name] = angle
            origin = joint.find("origin")
            if origin is None:
                origin = ET.SubElement(joint, "origin", xyz="0 0 0", rpy="0 0 0")
            rpy = np.array([float(v) for v in origin.get("rpy", "0 0 0").split()])
            axis_el = joint.find("axis")
            axis = np.array(
                [float(v) for v in (axis_el.get("xyz") if axis_el is not None else "1 0 0").split()]
            )
            rot = pin.rpy.rpyToMatrix(*rpy) @ _axis_rotation(axis, angle)
            origin.set("rpy", " ".join(f"{v:.17g}" for v in pin.rpy.matrixToRpy(rot)))
            joint.set("type", "fixed")
            for tag in ("mimic", "limit", "axis", "dynamics", "safety_controller"):
                for el in joint.findall(tag):
                    joint.remove(el)
    links = {link.get("name") for link in root.findall("link")}
    sole_parent: dict[str, str | None] = {}
    for side in SIDES:
        foot = getattr(rf.feet, side)
        name = f"{side}_sole_link"
        if foot.link == name and not any(foot.offset):
            sole_parent[side] = None
            continue
        if name in links:
            raise _err(
                rf,
                f"feet.{side}.link = {foot.link!r}: the URDF already has a link {name!r}; "
                f"expected the sole on it: feet.{side}.link = {name!r} with a zero offset",
            )
        sole_parent[side] = foot.link
        link = ET.SubElement(root, "link", name=name)
        inertial = ET.SubElement(link, "inertial")
        ET.SubElement(inertial, "origin", xyz="0 0 0", rpy="0 0 0")
        ET.SubElement(inertial, "mass", value="1e-4")
        ET.SubElement(
            inertial, "inertia", ixx="1e-8", ixy="0", ixz="0", iyy="1e-8", iyz="0", izz="1e-8"
        )
        joint = ET.SubElement(root, "joint", name=f"{side}_sole_fix_joint", type="fixed")
        ET.SubElement(joint, "parent", link=foot.link)
        ET.SubElement(joint, "child", link=name)
        ET.SubElement(joint, "origin", xyz=" ".join(str(v) for v in foot.offset), rpy="0 0 0")
    return ET.tostring(root, encoding="unicode"), sole_parent


def solve_posture(
    model, q: np.ndarray, sole_frames: dict[str, int], com_height: float | None = None,
    iterations: int = 30, targets: dict | None = None, com: np.ndarray | None = None,
) -> tuple[np.ndarray, float]:  # fmt: skip
    """The posture closest to ``q`` with the CoM above the middle of the soles (x, y) — and at
    ``com_height`` above them if given — and the soles where they are (flat, on the floor):
    Gauss-Newton on the legs and base position, e = [log6(oMf_d⁻¹ oMf) per sole; c - c_d],
    Δq = -J⁺ e (base orientation kept).  ``targets`` (side → SE3) and ``com`` (3,) replace the
    soles' and the CoM's goals.  Returns q and the final |e|."""
    import pinocchio as pin

    data = model.createData()
    q = q.copy()
    pin.framesForwardKinematics(model, data, q)
    if targets is None:
        targets = {s: data.oMf[f].copy() for s, f in sole_frames.items()}
    middle = np.mean([t.translation[:2] for t in targets.values()], axis=0)
    if com_height is not None:
        sole_z = np.mean([t.translation[2] for t in targets.values()])
        middle = np.r_[middle, sole_z + com_height]
    if com is not None:
        middle = np.asarray(com, dtype=float)
    rows_com = slice(0, 3 if (com_height is not None or com is not None) else 2)
    cols = np.r_[0:3, 6 : model.nv]  # base translation and joints
    norm = math.inf
    for _ in range(iterations):
        pin.framesForwardKinematics(model, data, q)
        pin.computeJointJacobians(model, data, q)
        com = pin.centerOfMass(model, data, q)
        errors, rows = [], []
        for s, f in sole_frames.items():
            errors.append(pin.log6(targets[s].actInv(data.oMf[f])).vector)
            rows.append(pin.getFrameJacobian(model, data, f, pin.LOCAL))
        errors.append(com[rows_com] - middle)
        rows.append(pin.jacobianCenterOfMass(model, data, q)[rows_com])
        e, J = np.concatenate(errors), np.vstack(rows)[:, cols]
        norm = float(np.linalg.norm(e))
        if norm < 1e-10:
            break
        dv = np.zeros(model.nv)
        dv[cols] = -np.linalg.lstsq(J, e, rcond=None)[0]
        q = pin.integrate(model, q, dv)
    return q, norm


def _com_height(model, data, q, sole_frames) -> float:
    import pinocchio as pin

    pin.framesForwardKinematics(model, data, q)
    sole_z = np.mean([data.oMf[f].translation[2] for f in sole_frames.values()])
    return float(pin.centerOfMass(model, data, q)[2] - sole_z)


def _posture_problem(model, data, q, sole_frames, limits, names, mass) -> str:
    """'' if q is a walkable standing posture: every joint JOINT_MARGIN_RAD inside its range and
    the whole weight held on either leg with ≤ TORQUE_FRACTION of each torque limit."""
    import pinocchio as pin

    for i, name in enumerate(names):
        lim, angle = limits[name], q[7 + i]
        if not lim.lower_rad + JOINT_MARGIN_RAD <= angle <= lim.upper_rad - JOINT_MARGIN_RAD:
            return f"{name} at {angle:.2f} rad reaches its range [{lim.lower_rad:.2f}, {lim.upper_rad:.2f}]"
    gravity = pin.computeGeneralizedGravity(model, data, q)
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    weight = np.array([0.0, 0.0, mass * GRAVITY, 0.0, 0.0, 0.0])
    for side, frame in sole_frames.items():
        # static single support with the CoM shifted above the stance sole: the weight's reaction
        # is a pure force at the sole (LWA), τ = g(q) - Jᵀ [0, 0, m g, 0, 0, 0]
        J = pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)
        wrench = weight
        tau = (gravity - J.T @ wrench)[6:]
        for i, name in enumerate(names):
            if abs(tau[i]) > TORQUE_FRACTION * limits[name].torque_nm:
                return (
                    f"{name} needs {abs(tau[i]):.0f} N m to hold the weight on the {side} leg "
                    f"(limit {limits[name].torque_nm:.0f} N m)"
                )
    return ""


def _longest_stride(
    model, q_nominal, sole_frames, limits, names, height, top, D, longest
) -> tuple[float, str]:  # fmt: skip
    """The longest step L (m, 1 cm steps up to ``longest``) whose touchdown posture exists: front
    sole REACH_FRACTION L ahead of the CoM, the rear one the rest behind, both flat, the CoM as
    high as the legs allow, H = min(standing, H_max − D + √(D² − (REACH_FRACTION L)²)) (the
    plan's height rule, dcmviz.gait.height), every leg joint inside its range (no margin: the
    range is where the reach ends)."""
    import pinocchio as pin

    data = model.createData()
    pin.framesForwardKinematics(model, data, q_nominal)
    base = {s: data.oMf[f].copy() for s, f in sole_frames.items()}
    mid = np.mean([t.translation for t in base.values()], axis=0)
    q, best, reason = q_nominal, 0.0, f"{STEP_LENGTH_PER_LEG} × hip → sole"
    L = 0.05
    while L <= longest + 1e-9:
        span = REACH_FRACTION * L
        h = min(height, top - D + math.sqrt(max(D * D - span * span, 0.0)))
        targets = {s: t.copy() for s, t in base.items()}
        targets["left"].translation = base["left"].translation + [span, 0.0, 0.0]
        targets["right"].translation = base["right"].translation - [L - span, 0.0, 0.0]
        q_try, residual = solve_posture(
            model, q, sole_frames, targets=targets, com=np.r_[mid[:2], mid[2] + h], iterations=50
        )
        if residual > 1e-6:
            return best, f"no touchdown posture for a {L:.2f} m step"
        for i, name in enumerate(names):
            lim, angle = limits[name], q_try[7 + i]
            if not lim.lower_rad <= angle <= lim.upper_rad:
                return best, f"{name} reaches its range at a {L:.2f} m step"
        best, q = L, q_try
        L = round(L + 0.01, 10)
    return max(best, longest), reason


def _derive(model, q_nominal, sole_frames, legs, joint_names, limits, rf) -> Derived:
    import pinocchio as pin

    data = model.createData()
    mass = float(pin.computeTotalMass(model))
    pin.framesForwardKinematics(model, data, q_nominal)
    height = _com_height(model, data, q_nominal, sole_frames)
    spacing = float(
        data.oMf[sole_frames["left"]].translation[1] - data.oMf[sole_frames["right"]].translation[1]
    )
    # straight legs: leg joints at zero, the rest as in the posture
    q0 = q_nominal.copy()
    for i, name in enumerate(joint_names):
        if any(name in leg for leg in legs.values()):
            q0[7 + i] = 0.0
    pin.framesForwardKinematics(model, data, q0)
    lengths = []
    for side, leg in legs.items():
        hip = data.oMi[model.getJointId(leg[0])].translation
        lengths.append(float(np.linalg.norm(hip - data.oMf[sole_frames[side]].translation)))
    leg_length = float(np.mean(lengths))  # hip → sole, the scale of the reach rules
    straight = _com_height(model, data, q0, sole_frames)
    highest = straight - STRAIGHT_MARGIN * leg_length
    # lowest: squat from the nominal posture in 1 cm steps while the posture stays walkable
    floor = LOWEST_HEIGHT_FRACTION * straight
    lowest, reason, q = (
        height,
        f"{LOWEST_HEIGHT_FRACTION:.0%} of the straight-leg height",
        q_nominal,
    )
    problem = _posture_problem(model, data, q_nominal, sole_frames, limits, joint_names, mass)
    if problem:
        raise _err(
            rf,
            f"the standing posture (CoM {height:.3f} m above the soles) is not walkable: "
            f"{problem}; expected a posture (posture, standing.com_height_m) with every leg "
            f"joint {JOINT_MARGIN_RAD} rad inside its range and the weight held on one leg",
        )
    h = height
    while h - 0.01 >= floor - 1e-9:
        q_try, residual = solve_posture(model, q, sole_frames, h - 0.01)
        problem = (
            "no posture found"
            if residual > 1e-6
            else _posture_problem(model, data, q_try, sole_frames, limits, joint_names, mass)
        )
        if problem:
            reason = problem
            break
        h, q = h - 0.01, q_try
        lowest = h
    # hip yaw: the leg joints whose axis is vertical standing; a turn needs them both ways
    pin.framesForwardKinematics(model, data, q_nominal)
    pin.computeJointJacobians(model, data, q_nominal)
    com_z = float(pin.centerOfMass(model, data, q_nominal)[2])

    def axis(name: str) -> np.ndarray:  # the joint's axis in the world, standing
        jid = model.getJointId(name)
        a = pin.getJointJacobian(model, data, jid, pin.LOCAL_WORLD_ALIGNED)[
            3:, model.joints[jid].idx_v
        ]
        return a / np.linalg.norm(a)

    # hip yaw: the leg joints whose axis is vertical standing; a turn needs them both ways
    yaw, turn = [], MAX_TURN_RAD
    hip_below, ankle_above = [], []
    for side, leg in legs.items():
        axes = {name: axis(name) for name in leg}
        for name in leg:
            if abs(axes[name][2]) > 0.9:
                yaw.append(name)
                lim = limits[name]
                turn = min(turn, TURN_PER_HIP_YAW * max(min(-lim.lower_rad, lim.upper_rad), 0.0))
        # hip: the most roll-like of the first 3 leg joints (axis along x); ankle: the most
        # pitch-like of the last 2 (axis along y)
        hip = max(leg[:3], key=lambda n: abs(axes[n][0]))
        ankle = max(leg[-2:], key=lambda n: abs(axes[n][1]))
        hip_below.append(com_z - data.oMi[model.getJointId(hip)].translation[2])
        sole_z = data.oMf[sole_frames[side]].translation[2]
        ankle_above.append(data.oMi[model.getJointId(ankle)].translation[2] - sole_z)
    hip_below_com, ankle_above_sole = float(np.mean(hip_below)), float(np.mean(ankle_above))
    foot_width = rf.feet.left.size[1]
    top = max(highest, height)
    D = top - hip_below_com - ankle_above_sole
    step_length, stride_reason = _longest_stride(
        model, q_nominal, sole_frames, limits, joint_names, height, top, D,
        STEP_LENGTH_PER_LEG * leg_length,
    )  # fmt: skip
    return Derived(
        mass_kg=mass,
        com_height_m=height,
        foot_spacing_m=spacing,
        hip_sole_m=leg_length,
        hip_below_com_m=hip_below_com,
        ankle_above_sole_m=ankle_above_sole,
        leg_length_m=max(highest, height) - hip_below_com - ankle_above_sole,
        straight_com_height_m=straight,
        min_com_height_m=min(lowest, height),
        max_com_height_m=max(highest, height),
        min_height_reason=reason,
        max_step_length_m=step_length,
        stride_reason=stride_reason,
        max_step_width_m=STEP_WIDTH_PER_LEG * leg_length,
        min_step_width_m=foot_width + FEET_GAP_M,
        max_step_height_m=STEP_HEIGHT_PER_LEG * leg_length,
        max_swing_speed_m_s=2 * step_length / FASTEST_SWING_S,
        max_turn_rad=turn,
        hip_yaw=tuple(yaw),
    )


def _spec(rf: RobotFile, d: Derived) -> RobotSpec:
    w = rf.walking

    def pick(key: str) -> float:
        pinned = getattr(w, key)
        return float(pinned) if pinned is not None else float(getattr(d, key))

    spec = RobotSpec(
        name=rf.name,
        mass_kg=pick("mass_kg"),
        com_height_m=pick("com_height_m"),
        foot_length_m=float(rf.feet.left.size[0]),
        foot_width_m=float(rf.feet.left.size[1]),
        foot_spacing_m=pick("foot_spacing_m"),
        max_step_length_m=pick("max_step_length_m"),
        max_step_width_m=pick("max_step_width_m"),
        min_step_width_m=pick("min_step_width_m"),
        max_step_height_m=pick("max_step_height_m"),
        max_swing_speed_m_s=pick("max_swing_speed_m_s"),
        min_com_height_m=pick("min_com_height_m"),
        max_com_height_m=pick("max_com_height_m"),
        bodies=dict(rf.bodies),
        max_turn_rad=pick("max_turn_rad"),
        leg_length_m=(
            float(w.leg_length_m)
            if w.leg_length_m is not None
            else pick("max_com_height_m") - d.hip_below_com_m - d.ankle_above_sole_m
        ),
    )
    if not spec.min_com_height_m <= spec.com_height_m <= spec.max_com_height_m:
        raise _err(
            rf,
            f"walking: the standing CoM height {spec.com_height_m:.3f} m is outside the walkable "
            f"heights {spec.min_com_height_m:.3f}–{spec.max_com_height_m:.3f} m; expected "
            "min_com_height_m ≤ com_height_m ≤ max_com_height_m",
        )
    if not spec.min_step_width_m <= spec.foot_spacing_m <= spec.max_step_width_m:
        raise _err(
            rf,
            f"walking: the standing foot spacing {spec.foot_spacing_m:.3f} m is outside the step "
            f"widths {spec.min_step_width_m:.3f}–{spec.max_step_width_m:.3f} m",
        )
    return spec


def _pinocchio_from_mjcf(rf: RobotFile, text: str):
    """Pinocchio's model of the edited MJCF text, with a free-flyer root joint."""
    import tempfile

    import pinocchio as pin

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "robot.xml")
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
        try:
            if hasattr(pin, "buildModelFromMJCFAndRootJoint"):  # pin ≥ 4.1
                built = pin.buildModelFromMJCFAndRootJoint(path, pin.JointModelFreeFlyer())
            else:  # (model, constraints): the edit leaves no equality constraints
                built = pin.buildModelFromMJCF(path, pin.JointModelFreeFlyer(), "root_joint")
        except Exception as err:  # noqa: BLE001 - Pinocchio raises plain exceptions
            raise _err(
                rf, f"model.mjcf = {rf.model.mjcf!r}: Pinocchio does not load the MJCF: {err}"
            ) from None
    return built[0] if isinstance(built, tuple) else built


def build_from_file(rf: RobotFile) -> RobotModel:
    """Build and check a parsed robot file; RobotFileError naming the key otherwise."""
    import pinocchio as pin

    mjcf_src = None
    if rf.mjcf_path:
        from dcmviz.robots import mjcf

        kind = "MJCF"
        mjcf_src = mjcf.load_mjcf(rf)
        legs = mjcf.legs(rf, mjcf_src)
        movable = dict(mjcf_src.movable)
    else:
        kind = "URDF"
        root = _parse_urdf(rf)
        legs = _legs(rf, root)
        movable = {
            j.get("name"): j.get("type") for j in root.findall("joint") if j.get("type") in MOVABLE
        }
    leg_joints = set(legs["left"]) | set(legs["right"])
    for name in rf.joints.keep:
        if movable.get(name) != "revolute":
            raise _err(
                rf,
                f"joints.keep: {name!r} is not a revolute joint of the {kind}; expected joints to "
                "actuate besides the legs",
            )
    actuated = leg_joints | set(rf.joints.keep)
    if rf.joints.lock is not None:
        for name in rf.joints.lock:
            if name not in movable or name in actuated:
                raise _err(
                    rf,
                    f"joints.lock: {name!r} is "
                    f"{'a leg or kept joint' if name in actuated else 'not a movable joint'}; "
                    "expected a movable joint that is neither a leg joint nor in joints.keep",
                )
        loose = sorted(set(movable) - actuated - set(rf.joints.lock))
        if loose:
            raise _err(
                rf,
                f"joints.lock: {', '.join(loose)} neither locked nor kept; expected every "
                "movable joint off the legs in joints.lock or joints.keep",
            )
    if mjcf_src is not None and rf.srdf_path is None and rf.model.reference_posture is not None:
        nominal = mjcf.keyframe_posture(rf, mjcf_src)
    else:
        nominal = srdf_state(rf)
    for name in rf.posture:
        if name not in movable:
            raise _err(
                rf,
                f"posture.{name}: no movable joint of that name in the {kind}; expected one of "
                f"{_suggest(sorted(movable), ('hip', 'knee', 'ankle'))}",
            )
    nominal.update(rf.posture)
    locked: dict[str, float] = {}
    if mjcf_src is not None:
        text, sole_parent = mjcf.edit_mjcf(rf, mjcf_src, actuated, nominal, locked)
        pm = _pinocchio_from_mjcf(rf, text)
    else:
        text, sole_parent = _edit_urdf(rf, root, actuated, nominal, locked)
        try:
            pm = pin.buildModelFromXML(text, pin.JointModelFreeFlyer())
        except Exception as err:  # noqa: BLE001 - Pinocchio raises plain exceptions
            raise _err(
                rf, f"model.urdf = {rf.model.urdf!r}: the URDF does not load: {err}"
            ) from None
    joint_names = tuple(pm.names[2:])
    if set(joint_names) != actuated:  # pragma: no cover - the edit keeps exactly these
        raise _err(rf, f"joints: unexpected actuated joints {joint_names}")
    sole_frames = {s: pm.getFrameId(f"{s}_sole_link") for s in SIDES}
    limits = {}
    for i, name in enumerate(joint_names):
        lim = LegLimits(
            float(pm.lowerPositionLimit[7 + i]),
            float(pm.upperPositionLimit[7 + i]),
            float(pm.effortLimit[6 + i]),
            float(pm.velocityLimit[6 + i]),
        )
        if not (lim.torque_nm > 0 and lim.lower_rad < lim.upper_rad):
            raise _err(
                rf,
                f"model.urdf: joint {name!r} has no <limit effort lower upper>; expected torque "
                "and position limits on every actuated joint"
                if rf.mjcf_path == ""
                else f"model.mjcf: joint {name!r} has no range or no torque limit; expected a "
                "range and an actuatorfrcrange (or a motor with a ctrlrange) on every actuated "
                "joint",
            )
        limits[name] = lim

    # nominal standing posture: soles flat on z = 0, centred at x = 0, CoM above their middle
    q = pin.neutral(pm)
    for i, j in enumerate(joint_names):
        q[7 + i] = nominal.get(j, 0.0)
    data = pm.createData()
    pin.framesForwardKinematics(pm, data, q)
    z = {s: data.oMf[f].translation[2] for s, f in sole_frames.items()}
    tilt = {
        s: math.degrees(math.acos(min(1.0, data.oMf[f].rotation[2, 2])))
        for s, f in sole_frames.items()
    }
    if abs(z["left"] - z["right"]) > 0.005 or max(tilt.values()) > 3.0:
        raise _err(
            rf,
            f"feet: the soles do not touch the ground together in the posture (left sole at "
            f"z = {z['left']:.3f} m tilted {tilt['left']:.1f}°, right at z = {z['right']:.3f} m "
            f"tilted {tilt['right']:.1f}°); expected both flat (≤ 3°) at the same height "
            "(± 5 mm): check feet.<side>.link/offset and the posture",
        )
    sole_z = np.mean([data.oMf[f].translation[2] for f in sole_frames.values()])
    sole_x = np.mean([data.oMf[f].translation[0] for f in sole_frames.values()])
    q[0] -= sole_x  # sole centres at x = 0
    q[2] = -sole_z  # soles on the floor
    q, residual = solve_posture(pm, q, sole_frames)
    if rf.standing.com_height_m is not None:
        q, residual = solve_posture(pm, q, sole_frames, rf.standing.com_height_m)
        if residual > 1e-6:
            raise _err(
                rf,
                f"standing.com_height_m = {rf.standing.com_height_m}: no standing posture with "
                f"the CoM that high above the soles (residual {residual:.2g}); expected a height "
                "the legs reach with bent knees",
            )
    mass = float(pin.computeTotalMass(pm))
    armature = rf.actuators.armature
    armature = ARMATURE_PER_KG * mass if armature is None else armature
    damping = rf.actuators.damping
    damping = DAMPING_PER_KG * mass if damping is None else damping
    pm.armature[6:] = armature
    derived = _derive(pm, q, sole_frames, legs, joint_names, limits, rf)
    return RobotModel(
        file=rf,
        urdf_text=text,
        pin_model=pm,
        joint_names=joint_names,
        legs=legs,
        locked=locked,
        nominal=nominal,
        sole_parent=sole_parent,
        sole_offset={s: tuple(getattr(rf.feet, s).offset) for s in SIDES},
        q_nominal=q,
        limits=limits,
        armature=float(armature),
        damping=float(damping),
        derived=derived,
        spec=_spec(rf, derived),
    )


@functools.lru_cache(maxsize=32)
def _build_cached(path: str, mtime_ns: int) -> RobotModel:
    return build_from_file(parse_robot_file(path))


def build_model(model: str) -> RobotModel:
    """The robot of ``robot.model`` (a built-in name or a robot file's path), built once per
    process and file version; RobotFileError naming the key otherwise."""
    path = resolve_robot_path(model)
    return _build_cached(path, Path(path).stat().st_mtime_ns)


def report(rm: RobotModel) -> str:
    """What was derived on load, what the file pins, and the limits (plain text)."""
    d, s, rf = rm.derived, rm.spec, rm.file
    lines = [
        f"{rf.name}: {rf.description}".rstrip(": "),
        f"  file {rf.path}",
        f"  model {rf.model_path}" + (f" (SRDF {rf.srdf_path})" if rf.srdf_path else ""),
        f"  legs: {', '.join(rm.legs['left'])} | {', '.join(rm.legs['right'])}",
        f"  kept: {', '.join(rf.joints.keep) or '-'}; locked: {len(rm.locked)} joints",
        f"  armature {rm.armature:.4g} kg m², damping {rm.damping:.4g} N m s/rad",
        f"  hip → sole {d.hip_sole_m:.3f} m; CoM {d.straight_com_height_m:.3f} m above the "
        "soles with straight legs",
        f"  standing: hip (roll) {d.hip_below_com_m:.3f} m below the CoM, ankle (pitch) "
        f"{d.ankle_above_sole_m:.3f} m above the sole",
        f"  lowest CoM stops at: {d.min_height_reason}",
        f"  longest step stops at: {d.stride_reason}",
        f"  hip yaw joints: {', '.join(d.hip_yaw) or '(none)'}",
    ]
    rows = (
        ("mass_kg", "kg"),
        ("com_height_m", "m"),
        ("min_com_height_m", "m"),
        ("max_com_height_m", "m"),
        ("foot_spacing_m", "m"),
        ("max_step_length_m", "m"),
        ("max_step_width_m", "m"),
        ("min_step_width_m", "m"),
        ("max_step_height_m", "m"),
        ("max_swing_speed_m_s", "m/s"),
        ("max_turn_rad", "rad"),
        ("leg_length_m", "m"),
    )
    for key, unit in rows:
        used, derived = getattr(s, key), getattr(d, key)
        pinned = getattr(rf.walking, key) is not None
        note = f"   (pinned; derived {derived:.3f})" if pinned else ""
        lines.append(f"  {key:22s} {used:8.3f} {unit}{note}")
    lo, hi = s.b_range_s
    lines.append(f"  b range {lo:.3f}–{hi:.3f} s (nominal {s.b_nominal_s:.3f} s)")
    lines.append(
        f"  feet {s.foot_length_m:.3f} × {s.foot_width_m:.3f} m; bodies: "
        + ", ".join(f"{k}→{v}" for k, v in s.bodies.items())
    )
    lines.append("  joint            range [rad]        torque [N m]  speed [rad/s]")
    for name, lim in rm.limits.items():
        lines.append(
            f"  {name:16s} [{lim.lower_rad:+.2f}, {lim.upper_rad:+.2f}]  {lim.torque_nm:10.1f}"
            f"  {lim.velocity_rad_s:8.2f}"
        )
    return "\n".join(lines)
