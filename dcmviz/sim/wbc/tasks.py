"""Tasks of the whole-body QP: ``compute(ctx, cmd) -> (A (k, nx), b (k,))``, cost weight ‖A x - b‖².

Each task is a small object; :class:`~dcmviz.sim.wbc.solver.WholeBodyController` sums them into
one QP, so adding a task never touches the solver.
"""

from __future__ import annotations

import math
import weakref
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from dcmviz import GRAVITY
from dcmviz.robots import SIDES, Robot
from dcmviz.sim.wbc.context import Context
from dcmviz.sim.wbc.layout import Layout
from dcmviz.walker.state import WalkerCommand


def _rot_z(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class Task(ABC):
    weight: float = 1.0
    constant_gram: np.ndarray | None = None  # AᵀA if it does not depend on the state
    constant_matrix: bool = False  # compute() always returns the same A (only b changes)

    @abstractmethod
    def compute(self, ctx: Context, cmd: WalkerCommand) -> tuple[np.ndarray, np.ndarray] | None:
        """(A, b) of the cost ‖A x − b‖², or None when the task is inactive this tick."""


class ContactForceTask(Task):
    """Σ_i f_i = contact_force (the walker's eq. 4 force plus gravity), scaled by 1/m."""

    def __init__(self, layout: Layout, mass: float, weight: float) -> None:
        self.weight = weight
        self.A = np.zeros((3, layout.nx))
        for s in SIDES:
            self.A[:, layout.wrench[s].start : layout.wrench[s].start + 3] = np.eye(3) / mass
        self.mass = mass
        self.constant_gram = self.A.T @ self.A
        self.constant_matrix = True

    def compute(self, ctx: Context, cmd: WalkerCommand) -> tuple[np.ndarray, np.ndarray]:
        return self.A, np.asarray(cmd.contact_force, dtype=float) / self.mass


class AngularMomentumTask(Task):
    """Σ_i (p_i - c) × f_i + τ_i = -k L - τ̂_s (moments about the CoM), scaled by 1/(m·1 m).

    τ̂_s is the sustained part of the estimated external moment about the CoM
    (:class:`MomentObserver`, :class:`SustainedLoad`): a pull held above the CoM is countered by
    the feet; the moment of a short push is not, it goes into the angular momentum (L̇ = τ̂ − τ̂_s
    − k L) and is given back at the rate k once the push is over."""

    def __init__(self, layout: Layout, mass: float, k: float, weight: float) -> None:
        self.layout, self.mass, self.k, self.weight = layout, mass, k, weight
        self.A = np.zeros((3, layout.nx))
        for s in SIDES:
            i = layout.wrench[s].start
            self.A[:, i + 3 : i + 6] = np.eye(3) / mass

    def compute(self, ctx: Context, cmd: WalkerCommand) -> tuple[np.ndarray, np.ndarray]:
        A, inv_m = self.A, 1.0 / self.mass
        cx, cy, cz = ctx.com.tolist()
        for s in SIDES:
            i = self.layout.wrench[s].start
            px, py, pz = ctx.sole_position[s].tolist()
            rx, ry, rz = (px - cx) * inv_m, (py - cy) * inv_m, (pz - cz) * inv_m
            A[0, i + 1], A[0, i + 2] = -rz, ry  # [r]× f
            A[1, i], A[1, i + 2] = rz, -rx
            A[2, i], A[2, i + 1] = -ry, rx
        return self.A, -(self.k * ctx.angular_momentum + ctx.sustained_moment) / self.mass


class BaseOrientationTask(Task):
    """ω̇_base = kp log(R_d Rᵀ) - kd ω, R_d = R_z(mean foot target yaw) R_0 (base ≡ locked
    torso), R_0 the base's standing orientation relative to the feet (``Robot.base_offset``:
    None for the identity).

    Leaning (``lean`` > 0, with the robot's ``mass``): a sustained external force F̂ (the walker's
    estimate, eq. 45) and moment τ̂ about the CoM (:class:`SustainedLoad`) hold the CoM
    d = (-z F̂_xy + (-τ̂_y, τ̂_x)) / (m g) away from the centre of pressure (the reference shift
    of eqs. 47–49 and ``moment_shift``, z the CoM height above the soles), so the whole robot
    leans along (d, z), as a person in a tug of war does.  R_d tilts the trunk ``lean`` × that
    far: upright, the trunk would hang its weight and the pull's moment on the stance hip
    (Talos: 160 N m, the hip roll limit, at 20 % of its weight) and the legs would bend sideways
    at the hips to their ranges.
    """

    def __init__(
        self,
        layout: Layout,
        kp: float,
        kd: float,
        weight: float,
        base_offset: np.ndarray | None = None,
        lean: float = 0.0,
        mass: float | None = None,
    ) -> None:
        self.kp, self.kd, self.weight = kp, kd, weight
        self.base_offset = base_offset
        self.lean = lean if mass else 0.0
        self.weight_n = (mass or 0.0) * GRAVITY
        self.A = np.zeros((3, layout.nx))
        self.constant_gram = np.zeros((layout.nx, layout.nx))
        self.constant_gram[3:6, 3:6] = np.eye(3)  # A = [0 R 0]: AᵀA = RᵀR = I
        # R_d of the last context, which is held weakly: a strong reference would keep the
        # previous tick's context (≈ 9 KB on Talos) alive after the backend has replaced it
        self._target: tuple[weakref.ref[Context], np.ndarray] | None = None

    def lean_rotation(self, ctx: Context, cmd: WalkerCommand) -> np.ndarray | None:
        """The tilt of R_d (3×3) for the present estimates, None when there is none."""
        fx, fy, _ = ctx.sustained_force.tolist()
        tx, ty, _ = ctx.sustained_moment.tolist()
        z = ctx.com.item(2) - min(p.item(2) for p in ctx.sole_position.values())
        dx = (-z * fx - ty) / self.weight_n
        dy = (-z * fy + tx) / self.weight_n
        d = math.hypot(dx, dy)
        if d < 1e-9 or z <= 0.0:
            return None
        angle = self.lean * math.atan2(d, z)
        return pin.exp3(np.array([-dy / d, dx / d, 0.0]) * angle)  # about e_z × d

    @staticmethod
    def heading(cmd: WalkerCommand) -> float:
        """The walking direction (rad): the feet's mean yaw, R_d's yaw."""
        y_l, y_r = cmd.feet["left"].yaw, cmd.feet["right"].yaw
        return math.atan2(math.sin(y_l) + math.sin(y_r), math.cos(y_l) + math.cos(y_r))

    def target(self, ctx: Context, cmd: WalkerCommand) -> np.ndarray:
        """R_d for this tick (computed once per context)."""
        cached = self._target
        if cached is not None and cached[0]() is ctx:
            return cached[1]
        yaw = self.heading(cmd)
        target = _rot_z(yaw) if self.base_offset is None else _rot_z(yaw) @ self.base_offset
        if self.lean:
            tilt = self.lean_rotation(ctx, cmd)
            if tilt is not None:
                target = tilt @ target
        self._target = (weakref.ref(ctx), target)
        return target

    def compute(self, ctx: Context, cmd: WalkerCommand) -> tuple[np.ndarray, np.ndarray]:
        err = pin.log3(self.target(ctx, cmd) @ ctx.base_rotation.T)
        self.A[:, 3:6] = ctx.base_rotation  # ω_world = R ω_local, ω̇_world = R ω̇_local
        return self.A, self.kp * err - self.kd * ctx.base_omega


@dataclass(frozen=True)
class AnkleStops:
    """The joints between a shank and its sole (ankle pitch and roll) and where they stop.

    ``v`` are their columns in v (and q̈), ``q`` their entries in q; ``lower``/``upper`` the
    range shrunk by the joint-limit margin (rad); ``horizon`` the look-ahead (s) of
    :class:`~dcmviz.sim.wbc.constraints.JointLimits`."""

    v: np.ndarray
    q: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    horizon: float

    @staticmethod
    def of(robot: Robot, side: str, margin: float, horizon: float) -> AnkleStops:
        model = robot.pin_model
        roll = model.frames[robot.sole_frames[side]].parentJoint
        joints = [model.parents[roll], roll]
        v = np.array([model.joints[j].idx_v for j in joints])
        q = np.array([model.joints[j].idx_q for j in joints])
        lower = model.lowerPositionLimit[q] + margin
        upper = model.upperPositionLimit[q] - margin
        return AnkleStops(v, q, lower, upper, horizon)

    @property
    def items(self) -> list[tuple[int, int, float, float]]:
        """Per joint (q index, v index, lower, upper) as plain numbers, for the per-tick path."""
        items = self.__dict__.get("_items")
        if items is None:
            items = list(zip(self.q.tolist(), self.v.tolist(), self.lower.tolist(),
                             self.upper.tolist(), strict=True))  # fmt: skip
            object.__setattr__(self, "_items", items)
        return items


# the swing sole's height row weighs more from this fraction of single support on, fully after
# LANDING_RAMP more (Gains.w_landing)
LANDING_FROM = 0.6
LANDING_RAMP = 0.3


class FootTask(Task):
    """Sole acceleration J q̈ + J̇ q̇ = a_ff + kp e + kd ė (position and yaw, roll/pitch flat).

    A foot scheduled as support that does not touch yet tracks a target ``touchdown_depth``
    below its footstep, so it lands firmly instead of hovering on the floor.  The swinging
    foot's height row weighs ``landing`` times more as it lands (LANDING_FROM of single support
    on), so that it arrives at rest where and when its path does.

    With ``ankle_stops``, the wanted angular acceleration turns each ankle joint no faster than
    its range allows (the bounds of the joint-limit constraint): the sole stays as flat as its
    ankle allows (a swing foot beside a low, wide stance cannot be flat: the G1's ankle roll
    stops at ±15°) instead of the QP rolling the hips and the base to flatten it.
    """

    def __init__(
        self,
        side: str,
        layout: Layout,
        kp: float,
        kd: float,
        weight: float,
        depth: float,
        landing: float = 1.0,
        ankle_stops: AnkleStops | None = None,
    ) -> None:
        self.side, self.kp, self.kd, self.weight = side, kp, kd, weight
        self.touchdown_depth = depth
        self.landing = landing
        self.A = np.zeros((6, layout.nx))
        self.nv = layout.nv
        self.ankle_stops = ankle_stops

    def compute(self, ctx: Context, cmd: WalkerCommand) -> tuple[np.ndarray, np.ndarray] | None:
        if ctx.active[self.side]:
            return None  # held by the stance constraint
        target = cmd.feet[self.side]
        # per component in plain floats (the same operations, in the same order, as on arrays)
        px, py, pz = np.asarray(target.position, dtype=float).tolist()
        if cmd.support[self.side]:  # scheduled down but not touching: keep going down
            pz -= self.touchdown_depth
        kp, kd = self.kp, self.kd
        sx, sy, sz = ctx.sole_position[self.side].tolist()
        wx, wy, wz, ox, oy, oz = ctx.sole_velocity[self.side].tolist()
        ax, ay, az = np.asarray(target.acceleration, dtype=float).tolist()
        ux, uy, uz = np.asarray(target.velocity, dtype=float).tolist()
        err = pin.log3(_rot_z(target.yaw) @ ctx.sole_rotation[self.side].T)
        ex, ey, ez = err.tolist()
        yaw_rate = float(target.yaw_rate)
        b = np.array(
            [
                ax + kp * (px - sx) + kd * (ux - wx),
                ay + kp * (py - sy) + kd * (uy - wy),
                az + kp * (pz - sz) + kd * (uz - wz),
                kp * ex + kd * (0.0 - ox),
                kp * ey + kd * (0.0 - oy),
                kp * ez + kd * (yaw_rate - oz),
            ]
        )
        jacobian = ctx.sole_jacobian[self.side]
        if self.ankle_stops is not None:
            b[3:] = self._within_stops(ctx, jacobian, b[3:])
        b -= ctx.sole_drift[self.side]
        self.A[:, : self.nv] = jacobian
        if self.landing != 1.0 and self.side == cmd.swing_side:
            u = min(max((cmd.swing_progress - LANDING_FROM) / LANDING_RAMP, 0.0), 1.0)
            if u > 0.0:  # the height row weighs 1 + (w_landing − 1) smoothstep(u) times more
                scale = math.sqrt(1.0 + (self.landing - 1.0) * u * u * (3.0 - 2.0 * u))
                self.A[2, : self.nv] *= scale
                b[2] *= scale
        return self.A, b

    def _within_stops(self, ctx: Context, jacobian: np.ndarray, wanted: np.ndarray) -> np.ndarray:
        """``wanted`` (ω̇, world) with its component along each ankle joint's axis (the joint's
        angular column of the sole Jacobian) limited to the joint acceleration its range allows,
        2 (q_lo - q - q̇ T)/T² ≤ q̈ ≤ 2 (q_hi - q - q̇ T)/T² (the bounds of JointLimits)."""
        stops = self.ankle_stops
        T = stops.horizon
        TT = T * T
        q, v = ctx.q, ctx.v
        lowest, highest = [], []
        within = True
        w0, w1, w2 = wanted.tolist()
        for iq, iv, lo, hi in stops.items:  # 2 (q_lo − (q + q̇ T)) / T², as floats
            ahead = q.item(iq) + v.item(iv) * T
            lowest.append(2.0 * (lo - ahead) / TT)
            highest.append(2.0 * (hi - ahead) / TT)
            a0, a1, a2 = jacobian.item(3, iv), jacobian.item(4, iv), jacobian.item(5, iv)
            along = (w0 * a0 + w1 * a1 + w2 * a2) / (a0 * a0 + a1 * a1 + a2 * a2)
            within = within and lowest[-1] <= along <= highest[-1]
        if within:
            return wanted  # no ankle joint at its stop (most ticks): nothing to limit
        axes = jacobian[3:, stops.v]
        for i in range(len(stops.v)):  # one joint after the other (the axes need not be square)
            axis = axes[:, i]
            along_i = float(wanted @ axis) / float(axis @ axis)
            allowed = min(max(along_i, lowest[i]), highest[i])
            if allowed != along_i:
                wanted = wanted + (allowed - along_i) * axis
        return wanted


class PostureTask(Task):
    """q̈_j = kp (q_nominal - q) - kd q̇ on the actuated joints."""

    def __init__(self, robot: Robot, layout: Layout, kp: float, kd: float, weight: float) -> None:
        self.kp, self.kd, self.weight = kp, kd, weight
        self.A = np.zeros((robot.nu, layout.nx))
        self.A[:, 6 : layout.nv] = np.eye(robot.nu)
        self.q_nominal = robot.q_nominal[7:].copy()
        self.constant_gram = self.A.T @ self.A
        self.constant_matrix = True

    def compute(self, ctx: Context, cmd: WalkerCommand) -> tuple[np.ndarray, np.ndarray]:
        return self.A, self.kp * (self.q_nominal - ctx.q[7:]) - self.kd * ctx.v[6:]
