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
``LEG_RADIUS_PER_FOOT_WIDTH`` × the foot's width) do not touch.

The region is two convex polygons in the stance frame, one in front of the stance foot and one
behind it (:class:`CrossoverRegion`), each the largest convex set of a grid of feasible touchdowns
(every grid point inside it feasible).  Derived once per robot (about a second).
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
GRID_M = 0.025  # spacing of the candidate touchdowns
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
    rm: RobotModel, stance: str, x: float, lateral: float, yaw: float = 0.0
) -> tuple[np.ndarray, float]:
    """Pinocchio q of the robot with its ``stance`` sole where it stands and the other sole flat
    at (``x``, ``lateral``) with ``yaw`` in the stance sole's frame, the CoM at the standing
    height above the middle of the soles, the base upright (its yaw free): Gauss-Newton from
    the standing posture.  Returns q and the final residual."""
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
    com_goal = np.array([middle[0], middle[1], base.translation[2] + height])
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
        e = np.concatenate(errors)
        residual = float(np.linalg.norm(e))
        if residual < 1e-9:
            break
        q = pin.integrate(model, q, -np.linalg.lstsq(np.vstack(rows), e, rcond=None)[0])
    return q, residual


def touchdown_problem(rm: RobotModel, stance: str, x: float, lateral: float) -> str:
    """'' if the robot can stand with its swinging foot at (``x``, ``lateral``) in the stance
    frame (:func:`touchdown_posture`), else what stops it."""
    import pinocchio as pin

    spec = rm.spec
    q, residual = touchdown_posture(rm, stance, x, lateral)
    if residual > 1e-6:
        return f"no posture (residual {residual:.1e})"
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
