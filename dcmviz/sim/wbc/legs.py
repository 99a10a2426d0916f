"""The legs keep clear of each other: a constraint of the whole-body QP (a crossing step).

Each leg is the chain of capsules MuJoCo collides (:mod:`dcmviz.robots.mujoco_model`: along hip →
knee → ankle → sole, radius ``r`` = half the sole's width).  Here each capsule's axis is sampled
by points fixed on its body (``Robot.leg_frames``, Pinocchio operational frames), and the
``ROWS`` closest left/right pairs closer than ``ACTIVE_M`` beyond the least distance get a row
like the joint ranges' (:class:`~dcmviz.sim.wbc.constraints.JointLimits`): the distance d between
the two points, projected a horizon T ahead, stays above d_min = 2 r + ``MARGIN_M``,

    d + ḋ T + ½ d̈ T² ≥ d_min,   d̈ = n · (J_a − J_b) q̈ + n · (a_a − a_b) (q̈ = 0),

n the unit vector from b to a, J the points' linear Jacobians and a their accelerations at
q̈ = 0 (world axes).  Soft in daqp: a leg that cannot be stopped in time is braked as hard as the
rest of the QP allows instead of making it infeasible.  Rows are void while the legs are far
apart (every ordinary step).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from dcmviz.robots import Robot
from dcmviz.robots.mujoco_model import LEG_RADIUS_PER_FOOT_WIDTH
from dcmviz.sim.wbc.constraints import INF, Constraint
from dcmviz.sim.wbc.context import Context
from dcmviz.sim.wbc.layout import Layout
from dcmviz.walker.state import WalkerCommand

ROWS = 6  # closest pairs constrained per tick
MARGIN_M = 0.01  # kept beyond the capsules' touching distance
ACTIVE_M = 0.10  # pairs within this of d_min get a row
HORIZON_S = 0.08  # look-ahead of the distance
_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


class LegClearance(Constraint):
    """Left and right leg capsules apart (module docstring)."""

    soft = True
    rows = ROWS

    def __init__(self, robot: Robot, layout: Layout) -> None:
        self.layout = layout
        self.frames = robot.leg_frames  # points along each leg's axis (Robot.leg_frames)
        radius = LEG_RADIUS_PER_FOOT_WIDTH * robot.foot_width
        self.d_min = 2.0 * radius + MARGIN_M
        self.last_distance = np.inf  # m, the closest pair's distance at the last tick

    def compute(
        self, ctx: Context, cmd: WalkerCommand, A: np.ndarray, lo: np.ndarray, up: np.ndarray
    ) -> bool:
        A[:] = 0.0
        lo[:], up[:] = -INF, INF
        model, data = ctx.model, ctx.data
        left = np.array([pin.updateFramePlacement(model, data, f).translation
                         for f in self.frames["left"]])  # fmt: skip
        right = np.array([pin.updateFramePlacement(model, data, f).translation
                          for f in self.frames["right"]])  # fmt: skip
        gaps = np.linalg.norm(left[:, None, :] - right[None, :, :], axis=2)
        self.last_distance = float(gaps.min())
        if self.last_distance > self.d_min + ACTIVE_M:
            return False
        order = np.argsort(gaps, axis=None)[: self.rows]
        nv = self.layout.nv
        T = HORIZON_S
        for row, flat in enumerate(order):
            i, j = np.unravel_index(flat, gaps.shape)
            d = float(gaps[i, j])
            if d > self.d_min + ACTIVE_M:
                break
            fa, fb = self.frames["left"][i], self.frames["right"][j]
            n = (left[i] - right[j]) / max(d, 1e-9)
            Ja = pin.getFrameJacobian(model, data, fa, _LWA)[:3]
            Jb = pin.getFrameJacobian(model, data, fb, _LWA)[:3]
            va = pin.getFrameVelocity(model, data, fa, _LWA).linear
            vb = pin.getFrameVelocity(model, data, fb, _LWA).linear
            aa = pin.getFrameClassicalAcceleration(model, data, fa, _LWA).linear
            ab = pin.getFrameClassicalAcceleration(model, data, fb, _LWA).linear
            rate = float(n @ (va - vb))
            A[row, :nv] = n @ (Ja - Jb)
            lo[row] = 2.0 * (self.d_min - d - rate * T) / (T * T) - float(n @ (aa - ab))
        return False
