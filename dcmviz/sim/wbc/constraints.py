"""Constraints of the whole-body QP: each fills its preallocated rows ``A``, ``lo``, ``up``.

``compute(ctx, cmd, A, lo, up) -> equality``; the solver stacks them into one constraint matrix.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np
import pinocchio as pin

from dcmviz.robots import SIDES, Robot
from dcmviz.robots.gains import Gains
from dcmviz.sim.wbc.context import Context
from dcmviz.sim.wbc.layout import Layout
from dcmviz.sim.wbc.tasks import BaseOrientationTask
from dcmviz.walker.state import WalkerCommand

INF = 1e30  # a bound daqp reads as none


class Constraint(ABC):
    rows: int
    soft: bool = False  # daqp may violate it if nothing else is feasible

    @abstractmethod
    def compute(
        self, ctx: Context, cmd: WalkerCommand, A: np.ndarray, lo: np.ndarray, up: np.ndarray
    ) -> bool:
        """Fill the preallocated rows ``A``, ``lo``, ``up``; return True for equalities."""


class FloatingBaseDynamics(Constraint):
    """Unactuated rows: M[:6] q̈ - Σ J_i[:, :6]ᵀ w_i = -h[:6] + w_ext.

    w_ext is the estimated external wrench on the base, the force F̂ (:class:`ForceObserver`)
    and the moment τ̂ about the CoM (:class:`MomentObserver`), in the base frame at its origin:
    [Rᵀ F̂; Rᵀ (τ̂ + (c - p_base) × F̂)].  A push on the upper body of a robot whose upper body
    is locked to the base acts on the base exactly so (its Jacobian has no joint columns): the
    joint torques then carry the push to the feet instead of the QP expecting accelerations the
    push cancels (a torso pull of 130 N on Talos: 4 rad/s² of trunk roll asked, 0.2 realised)."""

    rows = 6

    def __init__(self, layout: Layout) -> None:
        self.layout = layout

    def compute(
        self, ctx: Context, cmd: WalkerCommand, A: np.ndarray, lo: np.ndarray, up: np.ndarray
    ) -> bool:
        nv = self.layout.nv
        A[:, :nv] = ctx.M[:6]
        for s in SIDES:
            np.negative(ctx.sole_jacobian[s][:, :6].T, out=A[:, self.layout.wrench[s]])
        np.negative(ctx.h[:6], out=lo)
        force = ctx.external_force
        moment = ctx.external_moment
        fx, fy, fz = force.tolist()  # plain floats: numpy's per-call cost dominates on 3-vectors
        if fx or fy or fz or moment.any():
            rot_t = ctx.base_rotation.T
            lo[:3] += rot_t @ force
            rx, ry, rz = (ctx.com - ctx.q[:3]).tolist()  # (c - p_base) × F̂ (np.cross: ~50 µs)
            arm = np.array([ry * fz - rz * fy, rz * fx - rx * fz, rx * fy - ry * fx])
            lo[3:] += rot_t @ (moment + arm)
        up[:] = lo
        return True


class StanceFoot(Constraint):
    """A supporting foot in contact does not move: J q̈ + J̇ q̇ = -kd J q̇ (else void rows)."""

    rows = 6

    def __init__(self, side: str, layout: Layout, kd: float) -> None:
        self.side, self.layout, self.kd = side, layout, kd

    def compute(
        self, ctx: Context, cmd: WalkerCommand, A: np.ndarray, lo: np.ndarray, up: np.ndarray
    ) -> bool:
        if not ctx.active[self.side]:  # a void, always satisfied row (never a 0 = 0 equality)
            A[:] = 0.0
            lo[:], up[:] = -INF, INF
            return False
        A[:, : self.layout.nv] = ctx.sole_jacobian[self.side]
        lo[:] = up[:] = -ctx.sole_drift[self.side] - self.kd * ctx.sole_velocity[self.side]
        return True


class ContactWrenchCone(Constraint):
    """Friction pyramid |f_x|,|f_y| ≤ μ f_z, f_z ≥ f_min, CoP in the sole, |τ_z| ≤ μ_t f_z.

    Written in the sole frame (w_local = blockdiag(Rᵀ, Rᵀ) w): CoP x = -τ_y/f_z, y = τ_x/f_z.
    The torsion a sole can take when its CoP sits on the toe or heel edge (the sole then touches
    along that edge only, its two corners ±a_y apart) with half of the friction left for the
    horizontal force: μ_t = μ a_y / 2 (Talos 0.023 m, G1 0.011 m), unless ``gains.torsion``
    sets it.
    """

    rows = 11

    def __init__(self, side: str, layout: Layout, robot: Robot, gains: Gains) -> None:
        self.side, self.layout = side, layout
        mu = gains.friction
        lx = gains.cop_margin * robot.foot_length / 2
        ly = gains.cop_margin * robot.foot_width / 2
        mt = gains.torsion if gains.torsion is not None else 0.5 * mu * robot.foot_width / 2
        # rows over local [fx fy fz tx ty tz]
        self.C = np.array(
            [
                [1, 0, -mu, 0, 0, 0],
                [-1, 0, -mu, 0, 0, 0],
                [0, 1, -mu, 0, 0, 0],
                [0, -1, -mu, 0, 0, 0],
                [0, 0, -1, 0, 0, 0],
                [0, 0, -lx, 0, 1, 0],
                [0, 0, -lx, 0, -1, 0],
                [0, 0, -ly, 1, 0, 0],
                [0, 0, -ly, -1, 0, 0],
                [0, 0, -mt, 0, 0, 1],
                [0, 0, -mt, 0, 0, -1],
            ],
            dtype=float,
        )
        self.C_force, self.C_moment = self.C[:, :3].copy(), self.C[:, 3:].copy()
        self.min_force = gains.min_normal_force

    def compute(
        self, ctx: Context, cmd: WalkerCommand, A: np.ndarray, lo: np.ndarray, up: np.ndarray
    ) -> bool:
        rot_t = ctx.sole_rotation[self.side].T
        i = self.layout.wrench[self.side].start
        A[:, i : i + 3] = self.C_force @ rot_t
        A[:, i + 3 : i + 6] = self.C_moment @ rot_t
        lo[:] = -INF
        if ctx.active[self.side]:
            up[:] = 0.0
            up[4] = -self.min_force
        else:  # the wrench is bounded to zero: void rows (no degenerate 0 ≤ 0 constraints)
            up[:] = INF
        return False


class JointLimits(Constraint):
    """Joint ranges as acceleration bounds: q + q̇ T + ½ q̈ T² stays inside the range shrunk by a
    margin, i.e. 2 (q_lo - q - q̇ T)/T² ≤ q̈ ≤ 2 (q_hi - q - q̇ T)/T², but never asking a joint to
    brake (or to come back) harder than its torque can: each bound is kept within ±a_max,
    a_max = τ_max / M_jj / 2 (the joint's own torque limit and inertia, half of it left for
    gravity and the rest of the body). A joint that will overshoot anyway is braked as hard as
    it can instead of making the QP infeasible (soft in daqp as a last resort)."""

    soft = True

    def __init__(self, robot: Robot, layout: Layout, horizon: float, margin: float) -> None:
        self.layout, self.horizon = layout, horizon
        self.rows = robot.nu
        model = robot.pin_model
        self.lower = model.lowerPositionLimit[7:] + margin
        self.upper = model.upperPositionLimit[7:] - margin
        self.torque_limit = robot.torque_limit
        self._half_torque = 0.5 * robot.torque_limit
        self.eye = np.eye(robot.nu)
        self._filled: np.ndarray | None = None  # the rows A that hold the identity already

    def compute(
        self, ctx: Context, cmd: WalkerCommand, A: np.ndarray, lo: np.ndarray, up: np.ndarray
    ) -> bool:
        T = self.horizon
        if A is not self._filled:  # the same rows every tick: the identity is written once
            A[:, 6 : self.layout.nv] = self.eye
            self._filled = A
        ahead = ctx.q[7:] + ctx.v[6:] * T
        a_max = self._half_torque / ctx.M.diagonal()[6:]  # (0.5 τ_max) / M_jj
        TT = T * T
        np.minimum(2.0 * (self.lower - ahead) / TT, a_max, out=lo)
        np.maximum(2.0 * (self.upper - ahead) / TT, np.negative(a_max, out=a_max), out=up)
        return False


class TorqueLimits(Constraint):
    """-τ_max ≤ M[6:] q̈ + h[6:] - Σ J_i[:, 6:]ᵀ w_i ≤ τ_max."""

    def __init__(self, robot: Robot, layout: Layout) -> None:
        self.layout, self.limit = layout, robot.torque_limit
        self._lower = -robot.torque_limit
        self.rows = robot.nu

    def compute(
        self, ctx: Context, cmd: WalkerCommand, A: np.ndarray, lo: np.ndarray, up: np.ndarray
    ) -> bool:
        A[:, : self.layout.nv] = ctx.M[6:]
        for s in SIDES:
            np.negative(ctx.sole_jacobian[s][:, 6:].T, out=A[:, self.layout.wrench[s]])
        h = ctx.h[6:]
        np.subtract(self._lower, h, out=lo)
        np.subtract(self.limit, h, out=up)
        return False


class TrunkTilt(Constraint):
    """The trunk tilts sideways (roll, about the walking direction: the feet's mean yaw) at most
    θ_max from its target R_d (:class:`BaseOrientationTask`), and forwards and backwards (pitch)
    at most ``pitch_limit`` (None: θ_max as well; 0: free), braking with at most a: about each
    bounded axis the tilt rate ω may reach ω_max = sqrt(2 a (θ_max − θ − ω T)) (the rate it can
    still stop from before θ_max, from where it will be once ω̇ ≤ (ω_max − ω)/T has brought it
    there; negative, back, beyond it; the same below −θ_max).
    When the soles' CoP saturates the QP realises the asked force by tipping the trunk (the CMP
    leaves the CoP: a hip strategy); unbounded, Talos pushed towards its stance foot rolled
    0.42 rad in 0.4 s and sat on its hip-roll stops (±0.52 rad), unable to step.  Pitching, the
    hip strategy has the hips' pitch range (Talos ±2 rad against ±0.52 of roll) and bounding it
    cost Talos 6-13 % of the 0.2 s push it survives forwards and backwards.  Each bound is kept
    within ±4 a (a stop no harder than that); soft, as the joint ranges."""

    rows = 2
    soft = True

    def __init__(
        self, layout: Layout, task: BaseOrientationTask, limit: float, horizon: float,
        max_acceleration: float, pitch_limit: float | None = None,
    ) -> None:  # fmt: skip
        self.layout, self.task = layout, task
        self.limit, self.horizon, self.max_acceleration = limit, horizon, max_acceleration
        self.pitch_limit = limit if pitch_limit is None else pitch_limit

    def compute(
        self, ctx: Context, cmd: WalkerCommand, A: np.ndarray, lo: np.ndarray, up: np.ndarray
    ) -> bool:
        R = ctx.base_rotation
        yaw = self.task.heading(cmd)
        c, s = math.cos(yaw), math.sin(yaw)
        # rows 0, 1: about the walking direction (roll) and its left (pitch), in the world
        H = np.array([[c, s, 0.0], [-s, c, 0.0]])
        A[:, 3:6] = H @ R  # ω̇_world = R ω̇_local
        tilt = H @ -pin.log3(self.task.target(ctx, cmd) @ R.T)  # from R_d to R
        omegas = (H @ ctx.base_omega).tolist()
        a, T, stop = self.max_acceleration, self.horizon, 4.0 * self.max_acceleration
        for i, limit in enumerate((self.limit, self.pitch_limit)):
            omega = omegas[i]
            if limit <= 0.0:  # free
                lo[i], up[i] = -stop, stop
                continue
            ahead = float(tilt[i]) + omega * T  # where the rate is caught up with: brake there
            room_up, room_down = limit - ahead, limit + ahead
            fastest = math.copysign(math.sqrt(2.0 * a * abs(room_up)), room_up)
            slowest = -math.copysign(math.sqrt(2.0 * a * abs(room_down)), room_down)
            up[i] = min(max((fastest - omega) / T, -stop), stop)
            lo[i] = min(max((slowest - omega) / T, -stop), stop)
        return False
