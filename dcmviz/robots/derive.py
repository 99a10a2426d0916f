"""The numbers derived from a robot's model (docs/robots.md, "Derived numbers"): mass, walkable CoM
heights, reach, step limits, turn; and the :class:`~dcmviz.robots.spec.RobotSpec` with the robot
file's ``[walking]`` pins applied."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dcmviz.robots.file import RobotFile
from dcmviz.robots.file import file_error as _err
from dcmviz.robots.posture import (
    JOINT_MARGIN_RAD,
    com_height,
    posture_problem,
    solve_posture,
)
from dcmviz.robots.spec import RobotSpec

# rules that derive the walking numbers (docs/robots.md, "Derived numbers")
LOWEST_HEIGHT_FRACTION = (
    0.8  # a walkable posture has the CoM at least this fraction of the straight-leg height
)
STRAIGHT_MARGIN = 0.04  # highest CoM: straight-leg height − this × leg length (knees still bent)
STEP_LENGTH_PER_LEG = 0.55  # max |Δx| of a step per m of hip → sole (Talos 0.45 m / 0.81 m)
STEP_WIDTH_PER_LEG = 0.62  # max distance between the feet per m of leg length
STEP_HEIGHT_PER_LEG = 0.18  # max |Δz| of a step per m of leg length
FEET_GAP_M = 0.01  # min distance between the soles' inner edges
FASTEST_SWING_S = 0.5  # the swing foot crosses 2 × max step length in this time at most
REACH_FRACTION = 0.7  # at touchdown the front foot is this fraction of the step ahead of the CoM
TURN_PER_HIP_YAW = 0.5  # max turn per step per rad of the hip yaw's smaller side of its range
MAX_TURN_RAD = 0.5  # the preset schema's bound on gait.turn


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


def longest_stride(
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


def derive(model, q_nominal, sole_frames, legs, joint_names, limits, rf) -> Derived:
    import pinocchio as pin

    data = model.createData()
    mass = float(pin.computeTotalMass(model))
    pin.framesForwardKinematics(model, data, q_nominal)
    height = com_height(model, data, q_nominal, sole_frames)
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
    straight = com_height(model, data, q0, sole_frames)
    highest = straight - STRAIGHT_MARGIN * leg_length
    # lowest: squat from the nominal posture in 1 cm steps while the posture stays walkable
    floor = LOWEST_HEIGHT_FRACTION * straight
    lowest, reason, q = (
        height,
        f"{LOWEST_HEIGHT_FRACTION:.0%} of the straight-leg height",
        q_nominal,
    )
    problem = posture_problem(model, data, q_nominal, sole_frames, limits, joint_names, mass)
    if problem:
        raise _err(
            rf,
            f"the standing posture (CoM {height:.3f} m above the soles) is not walkable: "
            f"{problem}; expected a posture (posture, standing.com_height_m) with every "
            f"actuated joint (the legs' and any the file keeps, [joints] keep) "
            f"{JOINT_MARGIN_RAD} rad inside its range and the weight held on one leg",
        )
    h = height
    while h - 0.01 >= floor - 1e-9:
        q_try, residual = solve_posture(model, q, sole_frames, h - 0.01)
        problem = (
            "no posture found"
            if residual > 1e-6
            else posture_problem(model, data, q_try, sole_frames, limits, joint_names, mass)
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
    step_length, stride_reason = longest_stride(
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
        min_com_height_m=lowest,
        max_com_height_m=max(highest, height),
        min_height_reason=reason,
        max_step_length_m=step_length,
        stride_reason=stride_reason,
        max_step_width_m=STEP_WIDTH_PER_LEG * leg_length,
        min_step_width_m=foot_width + FEET_GAP_M,
        # on stairs the leg on the lower tread reaches down half the rise further (gait.height):
        # the rise is also bounded by twice how far the legs can lower the CoM (iCub, knees at
        # 28 of 30 N m standing: 1 cm, so 0.02 m stairs; it fell on 0.03 m ones unwarned)
        max_step_height_m=min(STEP_HEIGHT_PER_LEG * leg_length, 2.0 * (height - lowest)),
        max_swing_speed_m_s=2 * step_length / FASTEST_SWING_S,
        max_turn_rad=turn,
        hip_yaw=tuple(yaw),
    )


def robot_spec(rf: RobotFile, d: Derived) -> RobotSpec:
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
