"""Torque-level whole-body controller: small tasks and constraints feeding one QP (mink style).

Decision variables ``x = [q̈ (nv), w_left (6), w_right (6)]`` with ``w = [f; τ]`` the contact
wrench at the sole origin in world axes (the dual of the LOCAL_WORLD_ALIGNED sole Jacobian).
The torques follow from the actuated rows of the floating-base dynamics

    M q̈ + h = Sᵀ τ + Σ J_iᵀ w_i      ⇒      τ = (M q̈ + h - Σ J_iᵀ w_i)[6:].

Cost: ``Σ_k weight_k ‖A_k x - b_k‖²`` over the tasks; constraints: the 6 unactuated rows of the
dynamics (equality), stance feet held (equality), friction pyramid, unilateral normal force,
CoP inside the sole rectangle and torque limits. A foot gets a wrench only if it is *measured*
in contact *and* the walker schedules it as support; otherwise its wrench is bounded to zero and
it tracks the walker's foot target (swing, or coming down to touch down).
Solved with daqp (dense active set; fastest measured on this QP, see DESIGN.md).
"""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import daqp
import numpy as np
import pinocchio as pin

from dcmviz.sim.robots import SIDES, Robot
from dcmviz.state import WalkerCommand

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_INF = 1e30


def _rot_z(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass
class Gains:
    """Task gains (1/s², 1/s) and weights (dimensionless, on errors in m/s² or rad/s²)."""

    kp_foot: float = 600.0
    kd_foot: float = 50.0
    kp_base: float = 300.0
    kd_base: float = 35.0
    kp_posture: float = 30.0
    kd_posture: float = 10.0
    touchdown_depth: float = 0.01  # m below the footstep for a support foot not yet touching
    kd_stance: float = 10.0  # stance foot: a = -kd v (kills drift)
    k_angular_momentum: float = 5.0  # L̇ = -k L
    k_moment_observer: float = 10.0  # 1/s, external-moment observer gain (0: off)
    w_force: float = 1000.0
    w_angular_momentum: float = 0.5
    w_base: float = 3.0
    w_foot: float = 100.0
    w_posture: float = 0.05
    w_qdd_reg: float = 1e-5
    w_wrench_reg: float = 1e-4  # on w / m
    # Joint-range bounds are off by default: on 0.35 m steps the back knee reaches its stop and
    # MuJoCo's joint limit carries the load (10 steps done, DCM error ≤ 12 cm); with the bounds
    # the QP refuses the straight knee and Talos falls at t = 3.3 s. Normal steps never get near.
    joint_limits: bool = False
    joint_limit_horizon: float = 0.05  # s, look-ahead of the joint-range bounds
    joint_limit_margin: float = 0.02  # rad kept from each end of a joint's range
    friction: float = 0.7  # μ of the pyramid (MuJoCo's floor has 1.0)
    torsion: float = 0.02  # m, |τ_z| ≤ torsion · f_z
    min_normal_force: float = 5.0  # N on a support foot
    cop_margin: float = 0.9  # fraction of the half sole used for the CoP


@dataclass
class Context:
    """Everything the tasks need about the current state, computed once per tick by Pinocchio."""

    q: np.ndarray
    v: np.ndarray
    M: np.ndarray
    h: np.ndarray  # nle + joint damping
    com: np.ndarray
    com_velocity: np.ndarray
    angular_momentum: np.ndarray  # about the CoM, world axes
    base_rotation: np.ndarray
    base_omega: np.ndarray  # world axes
    sole_position: dict[str, np.ndarray] = field(default_factory=dict)
    sole_rotation: dict[str, np.ndarray] = field(default_factory=dict)
    sole_velocity: dict[str, np.ndarray] = field(default_factory=dict)  # (6,) [lin; ang], world
    sole_jacobian: dict[str, np.ndarray] = field(default_factory=dict)  # (6, nv) LWA
    sole_drift: dict[str, np.ndarray] = field(default_factory=dict)  # (6,) J̇ v, classical
    active: dict[str, bool] = field(default_factory=dict)  # wrench variable allowed
    external_moment: np.ndarray = field(default_factory=lambda: np.zeros(3))  # estimate, N m


class Kinematics:
    """Pinocchio evaluation of a :class:`Context` from (q, v)."""

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.model = robot.pin_model
        self.data = self.model.createData()
        self._zero = np.zeros(self.model.nv)
        self._damping = np.zeros(self.model.nv)
        self._damping[6:] = robot.damping

    def context(self, q: np.ndarray, v: np.ndarray) -> Context:
        """M, h, CoM, centroidal angular momentum, sole poses/Jacobians/drifts at (q, v)."""
        m, d = self.model, self.data
        pin.computeAllTerms(m, d, q, v)
        pin.computeCentroidalMomentum(m, d, q, v)
        pin.forwardKinematics(m, d, q, v, self._zero)
        pin.updateFramePlacements(m, d)
        x, y, z, w = q[3:7]  # base rotation from the unit quaternion (faster than data.oMi[1])
        rot = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
        ctx = Context(
            q=q,
            v=v,
            M=d.M.copy(),
            h=d.nle + self._damping * v,
            com=d.com[0].copy(),
            com_velocity=d.vcom[0].copy(),
            angular_momentum=d.hg.angular.copy(),
            base_rotation=rot,
            base_omega=rot @ v[3:6],
        )
        for side, fid in self.robot.sole_frames.items():
            placement = d.oMf[fid]
            ctx.sole_position[side] = placement.translation.copy()
            ctx.sole_rotation[side] = placement.rotation.copy()
            ctx.sole_jacobian[side] = pin.getFrameJacobian(m, d, fid, _LWA)
            ctx.sole_velocity[side] = pin.getFrameVelocity(m, d, fid, _LWA).vector.copy()
            ctx.sole_drift[side] = pin.getFrameClassicalAcceleration(m, d, fid, _LWA).vector.copy()
        return ctx


# --------------------------------------------------------------------------------------------
# tasks: ``compute(ctx, cmd) -> (A (k, nx), b (k,))``; cost weight ‖A x - b‖²
# --------------------------------------------------------------------------------------------


class Task(ABC):
    weight: float = 1.0
    constant_gram: np.ndarray | None = None  # AᵀA if it does not depend on the state

    @abstractmethod
    def compute(self, ctx: Context, cmd: WalkerCommand) -> tuple[np.ndarray, np.ndarray] | None:
        """(A, b) of the cost ‖A x − b‖², or None when the task is inactive this tick."""


class Layout:
    """Index ranges of q̈ and of each foot wrench inside x."""

    def __init__(self, nv: int) -> None:
        self.nv = nv
        self.wrench = {s: slice(nv + 6 * i, nv + 6 * i + 6) for i, s in enumerate(SIDES)}
        self.nx = nv + 12


class ContactForceTask(Task):
    """Σ_i f_i = contact_force (the walker's eq. 4 force plus gravity), scaled by 1/m."""

    def __init__(self, layout: Layout, mass: float, weight: float) -> None:
        self.weight = weight
        self.A = np.zeros((3, layout.nx))
        for s in SIDES:
            self.A[:, layout.wrench[s].start : layout.wrench[s].start + 3] = np.eye(3) / mass
        self.mass = mass
        self.constant_gram = self.A.T @ self.A

    def compute(self, ctx: Context, cmd: WalkerCommand) -> tuple[np.ndarray, np.ndarray]:
        return self.A, np.asarray(cmd.contact_force, dtype=float) / self.mass


class AngularMomentumTask(Task):
    """Σ_i (p_i - c) × f_i + τ_i = -k L - τ̂_ext (moments about the CoM), scaled by 1/(m·1 m).

    τ̂_ext is the estimated external moment about the CoM (:class:`MomentObserver`), so that a push
    above or below the CoM is countered by the feet instead of spinning the robot."""

    def __init__(self, layout: Layout, mass: float, k: float, weight: float) -> None:
        self.layout, self.mass, self.k, self.weight = layout, mass, k, weight
        self.A = np.zeros((3, layout.nx))
        for s in SIDES:
            i = layout.wrench[s].start
            self.A[:, i + 3 : i + 6] = np.eye(3) / mass

    def compute(self, ctx: Context, cmd: WalkerCommand) -> tuple[np.ndarray, np.ndarray]:
        A, inv_m = self.A, 1.0 / self.mass
        for s in SIDES:
            i = self.layout.wrench[s].start
            rx, ry, rz = (ctx.sole_position[s] - ctx.com) * inv_m
            A[0, i + 1], A[0, i + 2] = -rz, ry  # [r]× f
            A[1, i], A[1, i + 2] = rz, -rx
            A[2, i], A[2, i + 1] = -ry, rx
        return self.A, -(self.k * ctx.angular_momentum + ctx.external_moment) / self.mass


class BaseOrientationTask(Task):
    """ω̇_base = kp log(R_d Rᵀ) - kd ω, R_d = yaw of the mean foot target (base ≡ locked torso)."""

    def __init__(self, layout: Layout, kp: float, kd: float, weight: float) -> None:
        self.kp, self.kd, self.weight = kp, kd, weight
        self.A = np.zeros((3, layout.nx))
        self.constant_gram = np.zeros((layout.nx, layout.nx))
        self.constant_gram[3:6, 3:6] = np.eye(3)  # A = [0 R 0]: AᵀA = RᵀR = I

    def compute(self, ctx: Context, cmd: WalkerCommand) -> tuple[np.ndarray, np.ndarray]:
        y_l, y_r = cmd.feet["left"].yaw, cmd.feet["right"].yaw
        yaw = math.atan2(math.sin(y_l) + math.sin(y_r), math.cos(y_l) + math.cos(y_r))
        err = pin.log3(_rot_z(yaw) @ ctx.base_rotation.T)
        self.A[:, 3:6] = ctx.base_rotation  # ω_world = R ω_local, ω̇_world = R ω̇_local
        return self.A, self.kp * err - self.kd * ctx.base_omega


class FootTask(Task):
    """Sole acceleration J q̈ + J̇ q̇ = a_ff + kp e + kd ė (position and yaw, roll/pitch flat).

    A foot scheduled as support that does not touch yet tracks a target ``touchdown_depth``
    below its footstep, so it lands firmly instead of hovering on the floor.
    """

    def __init__(
        self, side: str, layout: Layout, kp: float, kd: float, weight: float, depth: float
    ) -> None:
        self.side, self.kp, self.kd, self.weight = side, kp, kd, weight
        self.touchdown_depth = depth
        self.A = np.zeros((6, layout.nx))
        self.nv = layout.nv

    def compute(self, ctx: Context, cmd: WalkerCommand) -> tuple[np.ndarray, np.ndarray] | None:
        if ctx.active[self.side]:
            return None  # held by the stance constraint
        target = cmd.feet[self.side]
        position = np.array(target.position, dtype=float)
        if cmd.support[self.side]:  # scheduled down but not touching: keep going down
            position[2] -= self.touchdown_depth
        b = np.empty(6)
        vel = ctx.sole_velocity[self.side]
        b[:3] = (
            np.asarray(target.acceleration)
            + self.kp * (position - ctx.sole_position[self.side])
            + self.kd * (np.asarray(target.velocity) - vel[:3])
        )
        err = pin.log3(_rot_z(target.yaw) @ ctx.sole_rotation[self.side].T)
        b[3:] = self.kp * err + self.kd * (np.array([0.0, 0.0, target.yaw_rate]) - vel[3:])
        b -= ctx.sole_drift[self.side]
        self.A[:, : self.nv] = ctx.sole_jacobian[self.side]
        return self.A, b


class PostureTask(Task):
    """q̈_j = kp (q_nominal - q) - kd q̇ on the actuated joints."""

    def __init__(self, robot: Robot, layout: Layout, kp: float, kd: float, weight: float) -> None:
        self.kp, self.kd, self.weight = kp, kd, weight
        self.A = np.zeros((robot.nu, layout.nx))
        self.A[:, 6 : layout.nv] = np.eye(robot.nu)
        self.q_nominal = robot.q_nominal[7:].copy()
        self.constant_gram = self.A.T @ self.A

    def compute(self, ctx: Context, cmd: WalkerCommand) -> tuple[np.ndarray, np.ndarray]:
        return self.A, self.kp * (self.q_nominal - ctx.q[7:]) - self.kd * ctx.v[6:]


# --------------------------------------------------------------------------------------------
# constraints: ``compute(ctx, cmd) -> (A (k, nx), lower (k,), upper (k,), equality: bool)``
# --------------------------------------------------------------------------------------------


class Constraint(ABC):
    rows: int
    soft: bool = False  # daqp may violate it if nothing else is feasible

    @abstractmethod
    def compute(
        self, ctx: Context, cmd: WalkerCommand, A: np.ndarray, lo: np.ndarray, up: np.ndarray
    ) -> bool:
        """Fill the preallocated rows ``A``, ``lo``, ``up``; return True for equalities."""


class FloatingBaseDynamics(Constraint):
    """Unactuated rows: M[:6] q̈ - Σ J_i[:, :6]ᵀ w_i = -h[:6]."""

    rows = 6

    def __init__(self, layout: Layout) -> None:
        self.layout = layout

    def compute(
        self, ctx: Context, cmd: WalkerCommand, A: np.ndarray, lo: np.ndarray, up: np.ndarray
    ) -> bool:
        nv = self.layout.nv
        A[:, :nv] = ctx.M[:6]
        for s in SIDES:
            A[:, self.layout.wrench[s]] = -ctx.sole_jacobian[s][:, :6].T
        lo[:] = up[:] = -ctx.h[:6]
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
            lo[:], up[:] = -_INF, _INF
            return False
        A[:, : self.layout.nv] = ctx.sole_jacobian[self.side]
        lo[:] = up[:] = -ctx.sole_drift[self.side] - self.kd * ctx.sole_velocity[self.side]
        return True


class ContactWrenchCone(Constraint):
    """Friction pyramid |f_x|,|f_y| ≤ μ f_z, f_z ≥ f_min, CoP in the sole, |τ_z| ≤ μ_t f_z.

    Written in the sole frame (w_local = blockdiag(Rᵀ, Rᵀ) w): CoP x = -τ_y/f_z, y = τ_x/f_z.
    """

    rows = 11

    def __init__(self, side: str, layout: Layout, robot: Robot, gains: Gains) -> None:
        self.side, self.layout = side, layout
        mu = gains.friction
        lx = gains.cop_margin * robot.foot_length / 2
        ly = gains.cop_margin * robot.foot_width / 2
        mt = gains.torsion
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
        lo[:] = -_INF
        if ctx.active[self.side]:
            up[:] = 0.0
            up[4] = -self.min_force
        else:  # the wrench is bounded to zero: void rows (no degenerate 0 ≤ 0 constraints)
            up[:] = _INF
        return False


class JointLimits(Constraint):
    """Joint ranges as soft acceleration bounds: q + q̇ T + ½ q̈ T² stays inside the range
    shrunk by a margin, i.e. 2 (q_lo - q - q̇ T)/T² ≤ q̈ ≤ 2 (q_hi - q - q̇ T)/T² (soft in daqp,
    so a joint already beyond its range never makes the QP infeasible)."""

    soft = True

    def __init__(self, robot: Robot, layout: Layout, horizon: float, margin: float) -> None:
        self.layout, self.horizon = layout, horizon
        self.rows = robot.nu
        model = robot.pin_model
        self.lower = model.lowerPositionLimit[7:] + margin
        self.upper = model.upperPositionLimit[7:] - margin
        self.eye = np.eye(robot.nu)

    def compute(
        self, ctx: Context, cmd: WalkerCommand, A: np.ndarray, lo: np.ndarray, up: np.ndarray
    ) -> bool:
        T = self.horizon
        A[:, 6 : self.layout.nv] = self.eye
        ahead = ctx.q[7:] + ctx.v[6:] * T
        lo[:] = 2.0 * (self.lower - ahead) / (T * T)
        up[:] = 2.0 * (self.upper - ahead) / (T * T)
        return False


class TorqueLimits(Constraint):
    """-τ_max ≤ M[6:] q̈ + h[6:] - Σ J_i[:, 6:]ᵀ w_i ≤ τ_max."""

    def __init__(self, robot: Robot, layout: Layout) -> None:
        self.layout, self.limit = layout, robot.torque_limit
        self.rows = robot.nu

    def compute(
        self, ctx: Context, cmd: WalkerCommand, A: np.ndarray, lo: np.ndarray, up: np.ndarray
    ) -> bool:
        A[:, : self.layout.nv] = ctx.M[6:]
        for s in SIDES:
            A[:, self.layout.wrench[s]] = -ctx.sole_jacobian[s][:, 6:].T
        lo[:] = -self.limit - ctx.h[6:]
        up[:] = self.limit - ctx.h[6:]
        return False


class MomentObserver:
    """External moment about the CoM from the centroidal angular momentum (the angular twin of
    the walker's eqs. 42–46): r = k_o (L(t) - L(0) - ∫ (τ_contact + r) dt), τ_contact the measured
    contact moments about the CoM; ṙ = k_o (τ_ext - r), a first-order estimate of τ_ext."""

    def __init__(self, gain: float) -> None:
        self.gain = gain
        self.reset(np.zeros(3))

    def reset(self, angular_momentum: np.ndarray) -> None:
        self.L0 = np.array(angular_momentum, dtype=float)
        self.integral = np.zeros(3)
        self.estimate = np.zeros(3)

    def update(self, angular_momentum: np.ndarray, contact_moment: np.ndarray, dt: float) -> None:
        self.integral += (contact_moment + self.estimate) * dt
        self.estimate = self.gain * (angular_momentum - self.L0 - self.integral)


# --------------------------------------------------------------------------------------------


@dataclass
class Solution:
    """The QP's answer for one tick."""

    tau: np.ndarray  # (nu,) N m, Pinocchio joint order
    qdd: np.ndarray  # (nv,)
    wrenches: dict[str, np.ndarray]  # side -> (6,) [f; τ] at the sole, world axes
    ok: bool  # False: the QP failed and the previous torques were kept
    exitflag: int


class WholeBodyController:
    """Builds and solves the QP from a list of tasks and constraints each tick."""

    def __init__(self, robot: Robot, gains: Gains | None = None) -> None:
        self.robot = robot
        self.gains = g = gains or Gains()
        self.layout = lay = Layout(robot.nv)
        self.kinematics = Kinematics(robot)
        mass = robot.mass
        self.tasks: list[Task] = [
            ContactForceTask(lay, mass, g.w_force),
            AngularMomentumTask(lay, mass, g.k_angular_momentum, g.w_angular_momentum),
            BaseOrientationTask(lay, g.kp_base, g.kd_base, g.w_base),
            *(FootTask(s, lay, g.kp_foot, g.kd_foot, g.w_foot, g.touchdown_depth) for s in SIDES),
            PostureTask(robot, lay, g.kp_posture, g.kd_posture, g.w_posture),
        ]
        self.constraints: list[Constraint] = [
            FloatingBaseDynamics(lay),
            *(StanceFoot(s, lay, g.kd_stance) for s in SIDES),
            *(ContactWrenchCone(s, lay, robot, g) for s in SIDES),
            TorqueLimits(robot, lay),
        ]
        if g.joint_limits:
            self.constraints.append(
                JointLimits(robot, lay, g.joint_limit_horizon, g.joint_limit_margin)
            )
        nx = lay.nx
        self.n_rows = sum(c.rows for c in self.constraints)
        self._A = np.zeros((self.n_rows, nx))
        self._lo = np.zeros(nx + self.n_rows)  # first nx: simple bounds on x
        self._up = np.zeros(nx + self.n_rows)
        self._sense = np.zeros(nx + self.n_rows, dtype=np.int32)
        self._reg = np.full(nx, g.w_qdd_reg)
        for s in SIDES:
            self._reg[lay.wrench[s]] = g.w_wrench_reg / mass**2
        self._H_constant = np.diag(self._reg)  # regularisation + state-independent AᵀA
        for task in self.tasks:
            if task.constant_gram is not None:
                self._H_constant += task.weight * task.constant_gram
        self._scale = np.ones(nx)
        self._scale[robot.nv :] = mass
        self._bounds_lo = np.zeros(nx + self.n_rows)
        self._bounds_up = np.zeros(nx + self.n_rows)
        self._tau = robot.torque_limit * 0.0
        self.timings = {"qp_build": 0.0, "qp_solve": 0.0}
        self.last: Solution | None = None
        self.failures = 0  # QPs that failed (previous torques held)

    def solve(self, ctx: Context, cmd: WalkerCommand, in_contact: dict[str, bool]) -> Solution:
        """τ for this tick; ``in_contact`` is the *measured* contact of each sole."""
        t0 = time.perf_counter()
        lay = self.layout
        nx, nv = lay.nx, lay.nv
        for s in SIDES:
            ctx.active[s] = bool(in_contact[s] and cmd.support[s])
        H = self._H_constant.copy()
        c = np.zeros(nx)
        for task in self.tasks:
            out = task.compute(ctx, cmd)
            if out is None:
                continue
            A, b = out
            wA = task.weight * A.T
            if task.constant_gram is None:
                H += wA @ A
            c -= wA @ b
        lo, up, sense = self._lo, self._up, self._sense
        lo[:nv], up[:nv] = -_INF, _INF
        sense[:] = 0
        for s in SIDES:
            sl = lay.wrench[s]
            if ctx.active[s]:
                lo[sl], up[sl] = -_INF, _INF
            else:
                lo[sl], up[sl] = 0.0, 0.0
                sense[sl] = 5
        row = 0
        for con in self.constraints:
            r = slice(row, row + con.rows)  # each constraint rewrites the same entries
            eq = con.compute(
                ctx, cmd, self._A[r], lo[nx + r.start : nx + r.stop], up[nx + r.start : nx + r.stop]
            )
            if eq:
                sense[nx + r.start : nx + r.stop] = 5
            elif getattr(con, "soft", False):
                sense[nx + r.start : nx + r.stop] = 8
            row += con.rows
        # solve in scaled variables x = D x' (wrenches in units of m·1 m/s²): H' = D H D, A' = A D
        d = self._scale
        self._bounds_lo[:] = lo
        self._bounds_up[:] = up
        self._bounds_lo[:nx] /= d
        self._bounds_up[:nx] /= d
        H_s, c_s, A_s = H * np.outer(d, d), c * d, self._A * d
        t1 = time.perf_counter()
        x, _, exitflag, _ = daqp.solve(H_s, c_s, A_s, self._bounds_up, self._bounds_lo, sense)
        x = x * d
        t2 = time.perf_counter()
        self.timings["qp_build"] += t1 - t0
        self.timings["qp_solve"] += t2 - t1
        ok = exitflag == 1 and bool(np.all(np.isfinite(x)))
        if ok:
            qdd = x[:nv]
            wr = {s: x[lay.wrench[s]].copy() for s in SIDES}
            tau = ctx.M[6:] @ qdd + ctx.h[6:]
            for s in SIDES:
                tau -= ctx.sole_jacobian[s][:, 6:].T @ wr[s]
            tau = np.clip(tau, -self.robot.torque_limit, self.robot.torque_limit)
            self._tau = tau
        else:
            self.failures += 1
            qdd = np.zeros(nv)
            wr = {s: np.zeros(6) for s in SIDES}
            tau = self._tau
        self.last = Solution(tau=tau, qdd=qdd.copy(), wrenches=wr, ok=ok, exitflag=int(exitflag))
        return self.last
