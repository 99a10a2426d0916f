"""Where a robot can cross its swinging foot over the stance foot: the crossover region.

A footstep lands "across" when its sole centre lies on the stance foot's far side or closer to it
than the feet's minimum width (``RobotSpec.min_step_width_m``), in the stance foot's frame with
the lateral axis towards the swinging foot's own side (as :mod:`dcmviz.robots.reach`): lateral
< min width.  Whether a crossed footstep is possible is a question of the legs: the hip must
adduct and yaw far enough, the soles must not overlap and the two legs must pass each other.
Each candidate is answered by a touchdown posture solved on the robot's Pinocchio model
(:func:`touchdown_posture`: the stance sole where it stands, the swinging sole flat at the
candidate, the CoM at the standing height above the middle of the soles, the base upright and
free to turn), accepted if every leg joint stays ``JOINT_MARGIN_RAD`` inside its range, the soles
keep ``SOLE_GAP_M`` apart and the legs (hip → knee → ankle → sole, capsules of radius
``LEG_RADIUS_PER_FOOT_WIDTH`` × the foot's width) do not touch.  (The whole-body QP keeps them
``LEG_MARGIN_M`` further apart, :mod:`dcmviz.sim.wbc.legs`; with that margin here the region
loses about 5 cm of crossing in front on Talos.)

The region is two convex polygons in the stance frame, one in front of the stance foot and one
behind it (:class:`CrossoverRegion`), each the largest convex set of a grid of feasible touchdowns
(every grid point inside it feasible).  Derived once per robot (about a second).

How far across a crossed foot can land depends on where the CoM is: the pelvis hangs above it,
and with the feet where they are the legs form an X whose crossing closes as the pelvis moves
away from the stance foot.  The region's touchdowns have the CoM above the middle of the soles,
which for a foot landing across puts the CoM beyond the stance foot, where a push towards the
stance foot may not have carried it by the time the foot lands.  :func:`reach_beyond_com` is the
crossing the legs reach past the CoM itself (``Robot.crossover_reach``; at any base yaw, the CoM
over the stance sole or 10 cm beyond it): on Talos 0.13 m in front of the stance foot and
0.17 m behind it, within 1 cm wherever the CoM stands in that range (tests/test_crossover.py),
against the 0.225 m past the stance foot's centre the region reaches.  A bound on crossing steps
reads the CoM at the landing (:func:`dcmviz.sweep.bounds.crossover_bound_at`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dcmviz.robots.geometry import convex_hull, rectangle_gap, sole_corners
from dcmviz.robots.model import RobotModel

JOINT_MARGIN_RAD = 0.05  # a crossed touchdown keeps each leg joint this far inside its range
SOLE_GAP_M = 0.02  # the soles' rectangles stay this far apart
LEG_RADIUS_PER_FOOT_WIDTH = 0.5  # legs as capsules this thick (× the sole's width)
LEG_MARGIN_M = 0.01  # the whole-body QP keeps the capsules this far apart (not the region)
GRID_M = 0.025  # spacing of the candidate touchdowns
COM_BEYOND_M = -0.1  # the CoM this far beyond the stance sole too (the reach past the CoM)
IK_ITERATIONS = 60


@dataclass(frozen=True)
class CrossoverRegion:
    """Crossed footsteps a robot can take: convex polygons (counter-clockwise, (n, 2): x forward,
    lateral towards the swinging foot's side) in the stance foot's frame, in front of it and
    behind it; an empty polygon where none is possible."""

    front: np.ndarray
    back: np.ndarray
    min_width_m: float  # lateral below this is "across" (the robot's min step width)
    leg_radius_m: float

    @property
    def polygons(self) -> tuple[np.ndarray, ...]:
        return tuple(p for p in (self.front, self.back) if len(p) >= 3)

    def contains(self, x: float, lateral: float, margin: float = 0.0) -> bool:
        """Whether (x, lateral) lies in one of the polygons, ``margin`` inside its edges."""
        return any(_inside(p, np.array([x, lateral]), margin) for p in self.polygons)

    def halfplanes(self, which: str) -> tuple[np.ndarray, np.ndarray]:
        """``A``, ``b`` with A p ≤ b exactly for p in polygon ``which`` ("front" | "back")."""
        return _halfplanes(self.front if which == "front" else self.back)


def _halfplanes(polygon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    edges = np.roll(polygon, -1, axis=0) - polygon
    normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1)  # outward for counter-clockwise
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return normals, np.einsum("ij,ij->i", normals, polygon)


def _inside(polygon: np.ndarray, point: np.ndarray, margin: float = 0.0) -> bool:
    if len(polygon) < 3:
        return False
    A, b = _halfplanes(polygon)
    return bool(np.all(A @ point <= b - margin + 1e-12))


def _segment_distance(p0, p1, q0, q1) -> float:
    """Closest distance (m) between the segments p0p1 and q0q1 (exact, clamped parameters)."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e, f = float(d1 @ d1), float(d2 @ d2), float(d2 @ r)
    c, b = float(d1 @ r), float(d1 @ d2)
    denom = a * e - b * b
    s = min(max((b * f - c * e) / denom, 0.0), 1.0) if denom > 1e-12 else 0.0
    t = (b * s + f) / e if e > 1e-12 else 0.0
    if t < 0.0:
        t, s = 0.0, min(max(-c / a, 0.0), 1.0) if a > 1e-12 else 0.0
    elif t > 1.0:
        t, s = 1.0, min(max((b - c) / a, 0.0), 1.0) if a > 1e-12 else 0.0
    return float(np.linalg.norm((p0 + s * d1) - (q0 + t * d2)))


def leg_points(rm: RobotModel, data, side: str, sole_frame: int) -> list[np.ndarray]:
    """The leg of ``side`` as a polyline: its joints' origins hip to ankle, then the sole centre
    (after forward kinematics in ``data``)."""
    model = rm.pin_model
    points = [data.oMi[model.getJointId(j)].translation.copy() for j in rm.legs[side]]
    points.append(data.oMf[sole_frame].translation.copy())
    return points


def legs_distance(rm: RobotModel, data, sole_frames: dict[str, int]) -> float:
    """Closest distance (m) between the two legs' polylines."""
    left = leg_points(rm, data, "left", sole_frames["left"])
    right = leg_points(rm, data, "right", sole_frames["right"])
    return min(
        _segment_distance(a0, a1, b0, b1)
        for a0, a1 in zip(left[:-1], left[1:], strict=True)
        for b0, b1 in zip(right[:-1], right[1:], strict=True)
    )


LEG_SAMPLE_SPACING_M = 0.05  # points along each leg's axis at most this far apart (clearance)
MIN_SEGMENT_M = 0.01  # leg segments shorter than this (joints at one point) are skipped


def leg_sample_points(rm: RobotModel, side: str) -> list[tuple[str, np.ndarray]]:
    """Points along the leg's axis (hip → knee → ankle → sole, every LEG_SAMPLE_SPACING_M at
    most), each as (joint name, position in that joint's frame) on the segment's first joint:
    what the whole-body QP keeps apart from the other leg's."""
    import pinocchio as pin

    model = rm.pin_model
    data = model.createData()
    pin.framesForwardKinematics(model, data, rm.q_nominal)
    joints = [model.getJointId(j) for j in rm.legs[side]]
    anchors = [data.oMi[j].translation.copy() for j in joints]
    anchors.append(data.oMf[model.getFrameId(f"{side}_sole_link")].translation.copy())
    points = []
    for i, (a, b) in enumerate(zip(anchors[:-1], anchors[1:], strict=True)):
        length = float(np.linalg.norm(b - a))
        if length < MIN_SEGMENT_M:
            continue
        n = max(1, math.ceil(length / LEG_SAMPLE_SPACING_M))
        placement = data.oMi[joints[i]]
        for k in range(n + 1):
            points.append((rm.legs[side][i], placement.actInv(a + (b - a) * k / n)))
    return points


def touchdown_posture(
    rm: RobotModel,
    stance: str,
    x: float,
    lateral: float,
    yaw: float = 0.0,
    com_lateral: float | None = None,
    base_yaw: float | None = None,
    q0: np.ndarray | None = None,
) -> tuple[np.ndarray, float]:
    """Pinocchio q of the robot with its ``stance`` sole where it stands and the other sole flat
    at (``x``, ``lateral``) with ``yaw`` in the stance sole's frame, the CoM at the standing
    height above the middle of the soles (or, with ``com_lateral``, halfway forward and that far
    from the stance sole's centre towards the swinging foot's side), the base upright, its yaw
    free (or ``base_yaw`` from the stance sole's: the posture's one free coordinate):
    Gauss-Newton from the standing posture (or ``q0``).  Returns q and the final residual."""
    import pinocchio as pin

    model = rm.pin_model
    data = model.createData()
    q = rm.q_nominal.copy()
    frames = {s: model.getFrameId(f"{s}_sole_link") for s in ("left", "right")}
    swing = "right" if stance == "left" else "left"
    sign = -1.0 if swing == "right" else 1.0  # lateral towards the swinging foot's side
    pin.framesForwardKinematics(model, data, q)
    base = data.oMf[frames[stance]].copy()
    offset = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, yaw), np.array([x, sign * lateral, 0.0]))
    targets = {stance: base, swing: base * offset}
    height = float(pin.centerOfMass(model, data, q)[2] - base.translation[2])
    middle = 0.5 * (targets["left"].translation + targets["right"].translation)
    if com_lateral is not None:  # the stance frame's lateral axis, towards the swinging side
        side_axis = base.rotation[:, 1] * sign
        middle = base.translation + 0.5 * x * base.rotation[:, 0] + com_lateral * side_axis
    com_goal = np.array([middle[0], middle[1], base.translation[2] + height])
    stance_yaw = math.atan2(base.rotation[1, 0], base.rotation[0, 0])
    if q0 is not None:
        q = np.array(q0, dtype=float)
    residual = math.inf
    for _ in range(IK_ITERATIONS):
        pin.framesForwardKinematics(model, data, q)
        pin.computeJointJacobians(model, data, q)
        errors, rows = [], []
        for s, frame in frames.items():
            errors.append(pin.log6(targets[s].actInv(data.oMf[frame])).vector)
            rows.append(pin.getFrameJacobian(model, data, frame, pin.LOCAL))
        errors.append(pin.centerOfMass(model, data, q) - com_goal)
        rows.append(pin.jacobianCenterOfMass(model, data, q))
        roll_pitch = pin.rpy.matrixToRpy(data.oMi[1].rotation)[:2]
        upright = np.zeros((2, model.nv))
        upright[:, 3:5] = np.eye(2)
        errors.append(roll_pitch)
        rows.append(upright)
        if base_yaw is not None:
            turn = pin.rpy.matrixToRpy(data.oMi[1].rotation)[2] - stance_yaw - base_yaw
            errors.append(np.array([math.remainder(turn, 2.0 * math.pi)]))
            row = np.zeros((1, model.nv))
            row[0, 5] = 1.0
            rows.append(row)
        e = np.concatenate(errors)
        residual = float(np.linalg.norm(e))
        if residual < 1e-9:
            break
        q = pin.integrate(model, q, -np.linalg.lstsq(np.vstack(rows), e, rcond=None)[0])
    return q, residual


def touchdown_problem(
    rm: RobotModel, stance: str, x: float, lateral: float, com_lateral: float | None = None
) -> str:
    """'' if the robot can stand with its swinging foot at (``x``, ``lateral``) in the stance
    frame (:func:`touchdown_posture`, the CoM as it places it), else what stops it."""
    q, residual = touchdown_posture(rm, stance, x, lateral, com_lateral=com_lateral)
    if residual > 1e-6:
        return f"no posture (residual {residual:.1e})"
    return posture_problem(rm, q)


def posture_problem(rm: RobotModel, q: np.ndarray) -> str:
    """'' if the standing posture q breaks none of the region's rules (joints inside their
    ranges, the soles and the legs apart), else the first it breaks."""
    import pinocchio as pin

    spec = rm.spec
    model = rm.pin_model
    for i, name in enumerate(rm.joint_names):
        lo = model.lowerPositionLimit[7 + i] + JOINT_MARGIN_RAD
        hi = model.upperPositionLimit[7 + i] - JOINT_MARGIN_RAD
        if not lo <= q[7 + i] <= hi:
            return f"{name} at {q[7 + i]:.2f} rad outside [{lo:.2f}, {hi:.2f}]"
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    frames = {s: model.getFrameId(f"{s}_sole_link") for s in ("left", "right")}
    corners = []
    for s in ("left", "right"):
        rotation = data.oMf[frames[s]].rotation
        yaw = math.atan2(rotation[1, 0], rotation[0, 0])
        corners.append(
            sole_corners(
                data.oMf[frames[s]].translation, yaw, spec.foot_length_m, spec.foot_width_m
            )
        )
    gap = float(rectangle_gap(corners[0][None], corners[1][None])[0])
    if gap < SOLE_GAP_M:
        return f"the soles {gap:.3f} m apart (< {SOLE_GAP_M} m)"
    clearance = legs_distance(rm, data, frames)
    needed = 2.0 * LEG_RADIUS_PER_FOOT_WIDTH * spec.foot_width_m
    if clearance < needed:
        return f"the legs {clearance:.3f} m apart (< {needed:.3f} m)"
    return ""


def derive_region(rm: RobotModel, stance: str = "left") -> CrossoverRegion:
    """The crossover region of the robot (module docstring), from a grid of touchdowns."""
    spec = rm.spec
    reach = spec.max_step_length_m
    xs = np.arange(-math.floor(reach / GRID_M), math.floor(reach / GRID_M) + 1) * GRID_M
    lows = np.arange(-math.floor(spec.max_step_width_m / GRID_M), 0) * GRID_M
    laterals = np.concatenate([lows, np.arange(0.0, spec.min_step_width_m - 1e-9, GRID_M)])
    feasible = {
        (float(x), float(y)): touchdown_problem(rm, stance, float(x), float(y)) == ""
        for x in xs
        for y in laterals
    }
    return CrossoverRegion(
        front=_largest_convex(feasible, front=True),
        back=_largest_convex(feasible, front=False),
        min_width_m=spec.min_step_width_m,
        leg_radius_m=LEG_RADIUS_PER_FOOT_WIDTH * spec.foot_width_m,
    )


YAW_STEP_RAD = 0.05  # the base yaw followed in these steps (touchdown_exists)
YAW_STEPS = 16  # ... this many each way at most
REACH_STEP_M = 0.01  # resolution of the reach past the CoM


def touchdown_exists(
    rm: RobotModel, stance: str, x: float, lateral: float, com_lateral: float | None = None
) -> bool:
    """Whether a touchdown at (``x``, ``lateral``) breaks none of the region's rules at *some*
    base yaw, the posture's one free coordinate (:func:`touchdown_problem` takes the solver's
    own): followed from the solver's answer in YAW_STEP_RAD steps both ways while the legs still
    reach (the hip yaws' ranges end it)."""
    import pinocchio as pin

    q, residual = touchdown_posture(rm, stance, x, lateral, com_lateral=com_lateral)
    if residual < 1e-6 and posture_problem(rm, q) == "":
        return True
    yaw0 = float(pin.rpy.matrixToRpy(pin.Quaternion(q[3:7]).toRotationMatrix())[2])
    for direction in (1.0, -1.0):
        start = q if residual < 1e-6 else None
        for k in range(1, YAW_STEPS + 1):
            start, res = touchdown_posture(
                rm, stance, x, lateral, com_lateral=com_lateral,
                base_yaw=yaw0 + direction * YAW_STEP_RAD * k, q0=start,
            )  # fmt: skip
            if res > 1e-6:
                break
            if posture_problem(rm, start) == "":
                return True
    return False


def reach_beyond_com(
    rm: RobotModel, stance: str, polygons: tuple[np.ndarray, ...]
) -> tuple[float, float, float]:
    """(reach, x, com): the farthest across (m past the CoM, towards the stance foot's far side)
    a crossed sole centre lands (:func:`touchdown_exists`, any base yaw), the CoM halfway forward
    and over the stance sole's centre or ``COM_BEYOND_M`` beyond it (where a push towards the
    stance foot carries it), and the x (stance frame) and CoM offset where it does: per x of the
    polygons' grid and CoM offset, the reach climbed in REACH_STEP_M steps from the best so far.
    (0, 0, 0) without a polygon.  Under a second on Talos."""
    best = (0.0, 0.0, 0.0)
    for polygon in polygons:
        if len(polygon) < 3:
            continue
        lo, hi = float(polygon[:, 0].min()), float(polygon[:, 0].max())
        for x in np.arange(lo, hi + 1e-9, GRID_M):
            for com in (0.0, COM_BEYOND_M):
                reach = best[0] + REACH_STEP_M
                while touchdown_exists(rm, stance, float(x), com - reach, com):
                    best = (reach, float(x), com)
                    reach += REACH_STEP_M
    return best


def _largest_convex(feasible: dict[tuple[float, float], bool], *, front: bool) -> np.ndarray:
    """The convex hull of the feasible grid points on one side (x > 0 or x < 0), shrunk (its
    most crossed rows dropped, then its farthest-out columns) until every grid point inside it
    is feasible; an empty (0, 2) array if nothing remains."""
    points = np.array([p for p, ok in feasible.items() if ok and (p[0] > 0) == front and p[0] != 0])
    grid = np.array([p for p in feasible if (p[0] > 0) == front and p[0] != 0])
    while len(points) >= 3:
        hull = convex_hull(points)
        if len(hull) >= 3 and np.linalg.matrix_rank(hull - hull[0]) == 2:
            A, b = _halfplanes(hull)
            inside = grid[np.all(grid @ A.T <= b + 1e-9, axis=1)]
            if all(feasible[(float(x), float(y))] for x, y in inside):
                return hull
        # drop the most crossed lateral row (the hardest touchdowns) and try again
        points = points[points[:, 1] > points[:, 1].min() + 1e-9]
    return np.zeros((0, 2))
