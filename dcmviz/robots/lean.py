"""How hard a robot's legs can lean against a sideways pull while it stands on one foot.

A pull F towards the swinging foot's side at a height z_p above the sole, held on one foot, needs
the centre of pressure z_p F / (m g) beyond the CoM on the pull's side (the moments about the CoP
of gravity and the pull cancel).  The CoP stays on the sole, so the CoM has to lean *outboard*
(away from the pull), past the stance sole: a fraction p = F / (m g) of the weight asks for the
CoM (z_p p - a_y) beyond the sole's centre even with the CoP on the sole's inner edge (a_y its
half width).  How far the CoM gets there is a question of the legs' joint ranges: the stance
leg tilts outwards at the ankle and hip roll, and with the trunk upright the hip joints sit
beside the pelvis, so a robot with wide hips and small roll ranges (the G1: ankle roll ±0.26 rad)
gets its CoM only a few centimetres past the sole.

:func:`lean_reach` finds that posture on the robot's Pinocchio model: the stance sole flat where it
stands, the CoM at the standing height, the other sole lifted and on its own side, every joint
inside its range, the base rolled by ``trunk_roll`` away from the pull (0: upright) — and the CoM
as far outboard as that allows (sequential QP, daqp).  The bound is static and no bound on walking:
the CoM sways back towards the pull between steps and never stands over the far foot (Talos
walks 30 % of m g against its 21.8 % here); it names the joint that runs out first.  A trunk rolled
further holds more again.  ``bench/robustness.py`` prints it next to its pull table.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dcmviz.robots.feet import OTHER

LIFT_M = 0.03  # the other sole at least this high
SOLE_GAP_WIDTHS = 1.2  # and at least this many sole widths beside the stance sole, on its side
STEP_RAD = 0.05  # trust region of one iteration, per coordinate
LIFT_STEP_M = 0.005
ITERATIONS = 300
MIN_STEP_RAD = 1e-4  # the lean stops once its steps shrank to this
PROJECTIONS = 20
BINDING_RAD = 1e-3  # a joint this close to an end of its range binds
TRUNK_WEIGHT = 100.0  # the base's roll target against the lean (a soft task)
TOLERANCE = 1e-8


@dataclass(frozen=True)
class Lean:
    """The posture that leans the CoM furthest outboard over one foot, and what it holds."""

    stance: str  # "left" | "right": the foot stood on (the pull is towards the other side)
    trunk_roll_rad: float  # the base's roll away from the pull in that posture (0: upright)
    com_outboard_m: float  # the CoM beyond the stance sole's centre, away from the pull
    pull_height_m: float  # the pull's height above the sole (the body's, standing)
    half_width_m: float  # the sole's half width: the CoP on its inner edge
    binding: tuple[str, ...]  # joints at an end of their range
    q: np.ndarray  # the posture (Pinocchio configuration)

    @property
    def pull_fraction(self) -> float:
        """The largest pull (fraction of m g) the posture holds: (outboard + a_y) / z_p."""
        return (self.com_outboard_m + self.half_width_m) / self.pull_height_m


def lean_reach(
    robot,
    trunk_roll: float = 0.0,
    stance: str = "right",
    body: str = "torso",
    ranges: dict[str, tuple[float, float]] | None = None,
) -> Lean:
    """The CoM leaned furthest outboard over ``stance`` (see the module), the base rolled by
    ``trunk_roll`` rad away from the pull; ``ranges`` replaces joints' ranges (rad), for what-ifs.
    The pull acts on ``body`` (a push target of the robot's spec), at its standing height."""
    import daqp
    import pinocchio as pin

    model = robot.pin_model
    data = model.createData()
    lower = model.lowerPositionLimit.copy()
    upper = model.upperPositionLimit.copy()
    for name, (lo, hi) in (ranges or {}).items():
        i = model.joints[model.getJointId(name)].idx_q
        lower[i], upper[i] = lo, hi
    stance_frame = robot.sole_frames[stance]
    other_frame = robot.sole_frames[OTHER[stance]]
    outboard = -1.0 if stance == "right" else 1.0  # the stance foot's outer side along y
    q = robot.q_nominal.copy()
    pin.framesForwardKinematics(model, data, q)
    sole = data.oMf[stance_frame].copy()
    base_nominal = data.oMi[1].rotation.copy()
    height = robot.com_height - sole.translation[2]
    # rolled away from the pull: the base's z axis tipped towards the stance foot's outer side
    target = pin.rpy.rpyToMatrix(-outboard * trunk_roll, 0.0, 0.0) @ base_nominal
    nv = model.nv
    half_gap = SOLE_GAP_WIDTHS * robot.foot_width
    sense = np.zeros(nv + 9, dtype=np.int32)
    sense[nv : nv + 7] = 5  # the stance sole and the CoM height: equalities

    def step(q: np.ndarray, radius: float, lean: bool) -> tuple[np.ndarray, float]:
        """One QP on the linearised problem: the step, and the CoM's outboard distance before."""
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        com = pin.centerOfMass(model, data, q)
        J_com = pin.jacobianCenterOfMass(model, data, q)
        J_sole = pin.getFrameJacobian(model, data, stance_frame, pin.LOCAL_WORLD_ALIGNED)
        J_other = pin.getFrameJacobian(model, data, other_frame, pin.LOCAL_WORLD_ALIGNED)
        placed = data.oMf[stance_frame]
        error = np.r_[
            placed.translation - sole.translation, pin.log3(placed.rotation @ sole.rotation.T)
        ]
        other = data.oMf[other_frame].translation - sole.translation
        A = np.vstack([J_sole, J_com[2:3], J_other[2:3], J_other[1:2]])
        rise = height - (com[2] - sole.translation[2])
        lift = min(LIFT_M - other[2], LIFT_STEP_M)  # lifted a little per iteration
        aside = -outboard * half_gap - other[1]  # the other sole on its own side
        lo = np.r_[-error, rise, lift, aside if outboard < 0 else -1e9]
        hi = np.r_[-error, rise, 1e9, aside if outboard > 0 else 1e9]
        step_lo = np.full(nv, -radius)
        step_hi = np.full(nv, radius)
        np.maximum(step_lo[6:], lower[7:] - q[7:], out=step_lo[6:])
        np.minimum(step_hi[6:], upper[7:] - q[7:], out=step_hi[6:])
        # the CoM outboard (``lean``), the base held at its target orientation (a soft task)
        base = data.oMi[1].rotation
        J_base = np.zeros((3, nv))
        J_base[:, 3:6] = base  # the base's angular velocity in world axes
        H = 1e-3 * np.eye(nv) + TRUNK_WEIGHT * J_base.T @ J_base
        f = TRUNK_WEIGHT * J_base.T @ pin.log3(base @ target.T)
        if lean:
            f -= outboard * J_com[1]
        x, _, flag, _ = daqp.solve(H, f, A, np.r_[step_hi, hi], np.r_[step_lo, lo], sense)
        if flag < 1:
            raise RuntimeError(f"lean_reach: {robot.name} on its {stance} foot: QP flag {flag}")
        return x, float(outboard * (com[1] - sole.translation[1]))

    def clip(q: np.ndarray) -> np.ndarray:
        """The joints inside their ranges (the QP's bounds hold to its tolerance, ~1e-9 rad)."""
        np.clip(q[7:], lower[7:], upper[7:], out=q[7:])
        return q

    radius, best = STEP_RAD, -np.inf
    for _ in range(ITERATIONS):  # lean, shrinking the steps once they stop gaining
        x, reached = step(q, radius, lean=True)
        if reached <= best + TOLERANCE:
            radius *= 0.5
            if radius < MIN_STEP_RAD:
                break
        best = max(best, reached)
        q = clip(pin.integrate(model, q, x))
    for _ in range(PROJECTIONS):  # then onto the constraints exactly (the steps were linearised)
        x, _ = step(q, STEP_RAD, lean=False)
        q = clip(pin.integrate(model, q, x))
        if np.abs(x).max() < 1e-12:
            break
    pin.framesForwardKinematics(model, data, q)
    com = pin.centerOfMass(model, data, q)
    placed = data.oMf[stance_frame]
    base = data.oMi[1].rotation @ base_nominal.T
    roll = float(np.arctan2(base[2, 1], base[2, 2]))
    names = robot.joint_names
    binding = tuple(
        name
        for name, i in zip(names, range(7, model.nq), strict=True)
        if q[i] <= lower[i] + BINDING_RAD or q[i] >= upper[i] - BINDING_RAD
    )
    return Lean(
        stance=stance,
        trunk_roll_rad=-outboard * roll,
        com_outboard_m=float(outboard * (com[1] - placed.translation[1])),
        pull_height_m=height + robot.push_lever_m(body),
        half_width_m=0.5 * robot.foot_width,
        binding=binding,
        q=q,
    )


def describe(robot, rolls: tuple[float, ...] = (0.0, 0.3)) -> str:
    """One line for ``python -m dcmviz.robots``: the pull the legs hold on one foot with the
    trunk upright and rolled, and the stance leg's joints that stop the lean upright."""
    leans = [lean_reach(robot, roll, "right") for roll in rolls]
    held = ", ".join(
        f"{100 * lean.pull_fraction:.1f} % of m g "
        + ("upright" if roll == 0.0 else f"with the trunk rolled {roll:g} rad")
        for roll, lean in zip(rolls, leans, strict=True)
    )
    leg = set(robot.model.legs["right"])
    stops = [joint for joint in leans[0].binding if joint in leg] or list(leans[0].binding)
    return (
        f"  on one foot, a sideways pull at the torso the legs lean against (statics): {held}; "
        f"upright, the lean stops at {', '.join(stops) or '-'}"
    )
