"""The legs keep clear of each other: a constraint of the whole-body QP (a crossing step).

Each leg is the chain of capsules MuJoCo collides (:mod:`dcmviz.robots.mujoco_model`: along hip →
knee → ankle → sole, radius ``r`` = half the sole's width).  Here each capsule's axis is sampled
by points fixed on its body (``Robot.leg_frames``, Pinocchio operational frames), and the
``ROWS`` closest left/right pairs closer than ``ACTIVE_M`` beyond the least distance get a row
like the joint ranges' (:class:`~dcmviz.sim.wbc.constraints.JointLimits`): the distance d between
the two points, projected a horizon T ahead, stays above d_min = 2 r + ``LEG_MARGIN_M``,

    d + ḋ T + ½ d̈ T² ≥ d_min,   d̈ = n · (J_a − J_b) q̈ + n · (a_a − a_b) (q̈ = 0),

n the unit vector from b to a, J the points' linear Jacobians and a their accelerations at
q̈ = 0 (world axes).  Soft in daqp: a leg that cannot be stopped in time is braked as hard as the
rest of the QP allows instead of making it infeasible.  Rows are void while the legs are far
apart, and on every tick of a walk whose recovery keeps each leg on its own side
(``WalkerCommand.legs_may_cross`` False: all strategies but ``crossover``): there the step widths
keep the legs apart, and the pairs would cost a tick's FK of every sample point for nothing (the
legs of Talos walk closer than d_min + ``ACTIVE_M``, so its rows were never void).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from dcmviz.robots import Robot
from dcmviz.robots.crossover import LEG_MARGIN_M
from dcmviz.robots.mujoco_model import LEG_RADIUS_PER_FOOT_WIDTH
from dcmviz.sim.wbc.constraints import INF, Constraint
from dcmviz.sim.wbc.context import Context
from dcmviz.sim.wbc.layout import Layout
from dcmviz.walker.state import WalkerCommand

ROWS = 6  # closest pairs constrained per tick
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
        self.d_min = 2.0 * radius + LEG_MARGIN_M  # as the crossover region's touchdowns
        self.last_distance = np.inf  # m, the closest pair's distance at the last tick
        # per-tick buffers: the points (world), their x, y, z differences and the gaps
        n_left, n_right = len(self.frames["left"]), len(self.frames["right"])
        self._left = np.zeros((n_left, 3))
        self._right = np.zeros((n_right, 3))
        self._dx, self._dy, self._dz, self._gaps = (np.zeros((n_left, n_right)) for _ in range(4))
        nv = layout.nv  # per row: J_a, J_b (3, nv), v_a, v_b, a_a, a_b (3,)
        self._rows = (
            *(np.zeros((ROWS, 3, nv)) for _ in range(2)),
            *(np.zeros((ROWS, 3)) for _ in range(4)),
        )

    def compute(
        self, ctx: Context, cmd: WalkerCommand, A: np.ndarray, lo: np.ndarray, up: np.ndarray
    ) -> bool:
        A[:] = 0.0
        lo[:], up[:] = -INF, INF
        if not cmd.legs_may_cross:  # each leg stays on its side (no crossover): void rows
            self.last_distance = np.inf
            return False
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
        order = np.argsort(gaps, axis=None)[: self.rows]
        closest = gaps.ravel()[order]
        near = closest <= self.d_min + ACTIVE_M  # a prefix: the gaps are in ascending order
        order, d = order[near], closest[near]
        r = order.size  # the closest pairs first: those within reach of d_min, one row each
        i, j = np.divmod(order, gaps.shape[1])
        n = (left[i] - right[j]) / np.maximum(d, 1e-9)[:, None]  # unit vectors b → a
        # each row's two points: Jacobians, velocities, accelerations (each frame read once)
        Ja, Jb, va, vb, aa, ab = (x[:r] for x in self._rows)
        point: dict[int, tuple] = {}
        for row, (k, m) in enumerate(zip(i.tolist(), j.tolist(), strict=True)):
            fa, fb = self.frames["left"][k], self.frames["right"][m]
            if fa not in point:
                point[fa] = _point(model, data, fa)
            if fb not in point:
                point[fb] = _point(model, data, fb)
            Ja[row], va[row], aa[row] = point[fa]
            Jb[row], vb[row], ab[row] = point[fb]
        n_row = n[:, None, :]
        rate = np.matmul(n_row, (va - vb)[:, :, None])[:, 0, 0]  # ḋ
        drift = np.matmul(n_row, (aa - ab)[:, :, None])[:, 0, 0]  # d̈ at q̈ = 0
        T = HORIZON_S
        A[:r, : self.layout.nv] = np.matmul(n_row, Ja - Jb)[:, 0, :]
        lo[:r] = 2.0 * (self.d_min - d - rate * T) / (T * T) - drift
        return False


def _point(model, data, frame: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A frame's linear Jacobian, velocity and acceleration at q̈ = 0 (world axes)."""
    return (
        pin.getFrameJacobian(model, data, frame, _LWA)[:3],
        pin.getFrameVelocity(model, data, frame, _LWA).linear,
        pin.getFrameClassicalAcceleration(model, data, frame, _LWA).linear,
    )
