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
        # per-tick buffers: the points (world), their x, y, z differences and the gaps
        n_left, n_right = len(self.frames["left"]), len(self.frames["right"])
        self._left = np.zeros((n_left, 3))
        self._right = np.zeros((n_right, 3))
        self._dx, self._dy, self._dz, self._gaps = (np.zeros((n_left, n_right)) for _ in range(4))

    def compute(
        self, ctx: Context, cmd: WalkerCommand, A: np.ndarray, lo: np.ndarray, up: np.ndarray
    ) -> bool:
        A[:] = 0.0
        lo[:], up[:] = -INF, INF
        model, data = ctx.model, ctx.data
        left, right = self._left, self._right
        for k, f in enumerate(self.frames["left"]):
            left[k] = pin.updateFramePlacement(model, data, f).translation
        for k, f in enumerate(self.frames["right"]):
            right[k] = pin.updateFramePlacement(model, data, f).translation
        # ‖left_i − right_j‖ of every pair, summed in np.linalg.norm's order, in buffers
        dx, dy, dz, gaps = self._dx, self._dy, self._dz, self._gaps
        np.subtract(left[:, 0, None], right[None, :, 0], out=dx)
        np.subtract(left[:, 1, None], right[None, :, 1], out=dy)
        np.subtract(left[:, 2, None], right[None, :, 2], out=dz)
        np.multiply(dx, dx, out=gaps)
        np.multiply(dy, dy, out=dy)
        np.multiply(dz, dz, out=dz)
        gaps += dy
        gaps += dz
        np.sqrt(gaps, out=gaps)
        self.last_distance = float(gaps.min())
        if self.last_distance > self.d_min + ACTIVE_M:
            return False
        order = np.argsort(gaps, axis=None)[: self.rows].tolist()
        nv = self.layout.nv
        n_right = gaps.shape[1]
        T = HORIZON_S
        point: dict[int, tuple] = {}  # frame id -> (J linear, velocity, acceleration), this tick
        for row, flat in enumerate(order):
            i, j = divmod(flat, n_right)
            d = float(gaps[i, j])
            if d > self.d_min + ACTIVE_M:
                break
            fa, fb = self.frames["left"][i], self.frames["right"][j]
            n = (left[i] - right[j]) / max(d, 1e-9)
            Ja, va, aa = point.get(fa) or point.setdefault(fa, _point(model, data, fa))
            Jb, vb, ab = point.get(fb) or point.setdefault(fb, _point(model, data, fb))
            rate = float(n @ (va - vb))
            A[row, :nv] = n @ (Ja - Jb)
            lo[row] = 2.0 * (self.d_min - d - rate * T) / (T * T) - float(n @ (aa - ab))
        return False


def _point(model, data, frame: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A frame's linear Jacobian, velocity and acceleration at q̈ = 0 (world axes)."""
    return (
        pin.getFrameJacobian(model, data, frame, _LWA)[:3],
        pin.getFrameVelocity(model, data, frame, _LWA).linear,
        pin.getFrameClassicalAcceleration(model, data, frame, _LWA).linear,
    )
