"""Standing postures: Gauss-Newton on the legs and the base with the soles held, and the test of
whether a posture is walkable (joint ranges, the weight held on one leg)."""

from __future__ import annotations

import math

import numpy as np

from dcmviz import GRAVITY
from dcmviz.robots.file import RobotFile
from dcmviz.robots.file import file_error as _err

JOINT_MARGIN_RAD = 0.05  # a walkable posture keeps each leg joint this far inside its range
TORQUE_FRACTION = 0.9  # … and holds the whole weight on one leg with ≤ this fraction of each limit


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
    cols = np.r_[0:3, _leg_columns(model, sole_frames)]  # base translation and the legs' joints
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


def _leg_columns(model, sole_frames: dict[str, int]) -> list[int]:
    """The v columns of the joints between the base and each sole (the legs): the other
    actuated joints (arms a robot file keeps) stay as the posture puts them; moving them too
    spread the CoM's correction over the arms and could take a shoulder out of its range."""
    cols: set[int] = set()
    for frame in sole_frames.values():
        joint = model.frames[frame].parentJoint
        while joint > 1:  # up to (not including) the floating base
            j = model.joints[joint]
            cols.update(range(j.idx_v, j.idx_v + j.nv))
            joint = model.parents[joint]
    return sorted(cols)


def com_height(model, data, q, sole_frames) -> float:
    import pinocchio as pin

    pin.framesForwardKinematics(model, data, q)
    sole_z = np.mean([data.oMf[f].translation[2] for f in sole_frames.values()])
    return float(pin.centerOfMass(model, data, q)[2] - sole_z)


def posture_problem(model, data, q, sole_frames, limits, names, mass) -> str:
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


FACING_TOLERANCE_DEG = 45.0  # a sole frame's x axis within this of the walking direction
MAX_SOLE_TILT_DEG = 15.0  # a reference posture's soles tilted more are a wrong sole frame


def standing_posture(
    rf: RobotFile, model, joint_names, nominal, sole_frames, base_xyzw: np.ndarray | None = None
) -> np.ndarray:
    """Pinocchio q of the nominal standing posture: the reference posture's joint angles and base
    orientation (``base_xyzw``, e.g. an SRDF ``root_joint``), the robot turned about z to face +x
    (its left foot on +y), soles flat on z = 0 and centred at x = 0, the CoM above their middle
    (and at ``standing.com_height_m`` if the file asks for it).  A file whose sole frames do not
    point the way the robot faces (mirrored feet, a sole link turned round) is refused."""
    import pinocchio as pin

    q = pin.neutral(model)
    if base_xyzw is not None:
        q[3:7] = base_xyzw
    for i, j in enumerate(joint_names):
        q[7 + i] = nominal.get(j, 0.0)
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    z = {s: data.oMf[f].translation[2] for s, f in sole_frames.items()}
    tilt = {
        s: math.degrees(math.acos(min(1.0, data.oMf[f].rotation[2, 2])))
        for s, f in sole_frames.items()
    }
    if abs(z["left"] - z["right"]) > 0.005 or max(tilt.values()) > MAX_SOLE_TILT_DEG:
        raise _err(
            rf,
            f"feet: the soles do not touch the ground together in the posture (left sole at "
            f"z = {z['left']:.3f} m tilted {tilt['left']:.1f}°, right at z = {z['right']:.3f} m "
            f"tilted {tilt['right']:.1f}°); expected both about flat (≤ {MAX_SOLE_TILT_DEG:.0f}°) "
            "at the same height (± 5 mm): check feet.<side>.link/offset and the posture"
            + ("" if base_xyzw is None else " (the base as the reference posture turns it)"),
        )
    q = _facing_forward(rf, model, data, q, sole_frames)
    pin.framesForwardKinematics(model, data, q)
    sole_z = np.mean([data.oMf[f].translation[2] for f in sole_frames.values()])
    sole_x = np.mean([data.oMf[f].translation[0] for f in sole_frames.values()])
    q[0] -= sole_x  # sole centres at x = 0
    q[2] -= sole_z  # soles on the floor
    # the soles flat on the floor where they stand (yaw kept), the CoM above their middle
    pin.framesForwardKinematics(model, data, q)
    flat = {}
    for s, f in sole_frames.items():
        placement = data.oMf[f]
        x_axis = placement.rotation[:, 0]
        yaw = math.atan2(x_axis[1], x_axis[0])
        flat[s] = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, yaw), placement.translation.copy())
    q, residual = solve_posture(model, q, sole_frames, targets=flat, iterations=50)
    if residual > 1e-6:
        raise _err(
            rf,
            f"feet: no posture near the reference one stands on both soles flat (residual "
            f"{residual:.2g}); expected a reference posture with the soles about flat",
        )
    if rf.standing.com_height_m is not None:
        q, residual = solve_posture(model, q, sole_frames, rf.standing.com_height_m)
        if residual > 1e-6:
            raise _err(
                rf,
                f"standing.com_height_m = {rf.standing.com_height_m}: no standing posture with "
                f"the CoM that high above the soles (residual {residual:.2g}); expected a height "
                "the legs reach with bent knees",
            )
    return q


def _facing_forward(rf: RobotFile, model, data, q: np.ndarray, sole_frames) -> np.ndarray:
    """``q`` turned about the vertical so that the robot faces +x: its left sole on +y of its
    right one (a robot whose base frame points backwards, iCub's say, turns by π).  Then each
    sole frame's x axis must point forwards; one that does not means mirrored feet (feet.left on
    the right leg) or a sole link turned round."""
    import pinocchio as pin

    left, right = (data.oMf[sole_frames[s]].translation for s in ("left", "right"))
    across = left[:2] - right[:2]
    if float(np.linalg.norm(across)) < 1e-3:
        raise _err(
            rf,
            "feet: the left and right soles stand on the same spot in the posture; expected "
            "feet.left.link and feet.right.link on the two legs",
        )
    heading = math.atan2(-across[0], across[1])  # forward = left-to-right axis turned by −90°
    if abs(heading) > 1e-9:
        turn = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, -heading), np.zeros(3))
        base = pin.XYZQUATToSE3(q[:7])
        q = q.copy()
        q[:7] = pin.SE3ToXYZQUAT(turn * base)
        pin.framesForwardKinematics(model, data, q)
    for side, frame in sole_frames.items():
        x_axis = data.oMf[frame].rotation[:2, 0]
        off = math.degrees(math.atan2(x_axis[1], x_axis[0]))
        if abs(off) > FACING_TOLERANCE_DEG:
            raise _err(
                rf,
                f"feet.{side}.link = {getattr(rf.feet, side).link!r}: its sole frame's x axis "
                f"points {off:+.0f}° from the way the robot faces (its left foot on its left, "
                f"{'turned by ' + format(math.degrees(-heading), '+.0f') + '° to face +x' if abs(heading) > 1e-9 else 'facing +x'}); "
                "expected each sole frame with x forward and z up: are feet.left and feet.right "
                "swapped (mirrored), or is the sole link turned round?",
            )
    return q
