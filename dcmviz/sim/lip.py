"""Reduced model: a point mass with the robot's mass on massless legs (the LIP of eqs. 1–4).

The feet can only push with a force along the line from the contact point (eCMP) to the CoM, so
the realised VRP of the contact force, v_c = x − b²/m (F_c − m g e_z), has its horizontal part
inside the support polygon (the sole rectangles of the feet in contact, or their convex hull in
double support).  The walker's desired contact force is realised after projecting v_c onto that
polygon; external forces act on the CoM.  Over one control period v_c is held and the linear
dynamics ẍ = (x − v_c)/b² + F_ext/m are integrated exactly (cosh/sinh).

The robot is counted as fallen when its DCM is farther from the support polygon than one maximal
step can reach (no single step can capture it) or the CoM drops below half its height.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dcmviz import GRAVITY
from dcmviz.gait.terrain import Terrain
from dcmviz.robots import Robot, RobotSpec
from dcmviz.robots.feet import SIDES
from dcmviz.robots.geometry import convex_hull, project_to_polygon, sole_corners
from dcmviz.walker.state import MeasuredState, WalkerCommand

E_Z = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class LipState:
    """Everything the point mass needs to continue exactly from one tick (:meth:`LipBackend.get_state`)."""

    ticks: int
    com: np.ndarray  # (3,) m
    com_velocity: np.ndarray  # (3,) m/s
    feet: dict[str, np.ndarray]
    feet_yaw: dict[str, float]
    in_contact: dict[str, bool]
    applied: np.ndarray  # (3,) N, the contact force of the last tick
    cop: np.ndarray  # (3,) m, its centre of pressure
    support_distance: float
    external: dict[str, np.ndarray]
    fell: bool


class LipBackend:
    """Point-mass backend with the same interface as the MuJoCo humanoid."""

    name = "lip"

    def __init__(
        self, robot: Robot, *, control_dt: float = 0.005, terrain: Terrain | None = None
    ) -> None:
        self.robot = robot
        self.spec: RobotSpec = robot.spec
        self.terrain = terrain if terrain is not None else Terrain()
        self.mass = self.spec.mass_kg
        self.b = self.spec.b_nominal_s  # of the robot standing at its own CoM height
        self.control_dt = float(control_dt)
        self.external: dict[str, np.ndarray] = {}
        self.reset()

    # -- interface ------------------------------------------------------------------------------
    def reset(self) -> MeasuredState:
        half = 0.5 * self.spec.foot_spacing_m
        z = self.terrain.height_at(np.array([[0.0, half], [0.0, -half]]))  # standing on the ground
        self.feet = {"left": np.array([0.0, half, z[0]]), "right": np.array([0.0, -half, z[1]])}
        self.feet_yaw = {"left": 0.0, "right": 0.0}
        self.in_contact = {"left": True, "right": True}
        self.t = 0.0
        self._ticks = 0  # the clock counts ticks: t = ticks · dt never drifts off a phase boundary
        ground = max(float(z[0]), float(z[1]))
        self.com = np.array([0.0, 0.0, ground + self.spec.com_height_m])  # the robot's height
        self.com_velocity = np.zeros(3)
        self.applied = self.mass * GRAVITY * E_Z
        self.cop = np.array([0.0, 0.0, ground])  # centre of pressure of the contact force
        self.support_distance = 0.0  # how far the asked VRP lay outside the support polygon
        self.external = {}
        self._external_sum = np.zeros(3)
        self._fell = False
        self._polygon_key = None
        return self.measure()

    def measure(self) -> MeasuredState:
        return MeasuredState(
            t=self.t,
            com=self.com.copy(),
            com_velocity=self.com_velocity.copy(),
            feet={s: p.copy() for s, p in self.feet.items()},
            feet_yaw=dict(self.feet_yaw),
            in_contact=dict(self.in_contact),
            mass=self.mass,
            applied_contact_force=self.applied.copy(),
        )

    def set_external_force(self, body: str, force: np.ndarray) -> None:
        """A persistent world-frame force (N); on the point mass every body is the CoM."""
        force = np.asarray(force, dtype=float)
        if force.shape != (3,) or not np.all(np.isfinite(force)):
            raise ValueError(f"force = {force!r}: must be 3 finite numbers (N)")
        if body not in self.spec.bodies and body not in self.spec.bodies.values():
            raise ValueError(f"body = {body!r}: unknown; allowed: {', '.join(self.spec.bodies)}")
        self.external[body] = force
        self._external_sum = sum(self.external.values(), np.zeros(3))

    def external_force(self) -> np.ndarray:
        return self._external_sum

    def fell(self) -> bool:
        return self._fell

    def support_polygon(self) -> np.ndarray:
        key = tuple(
            (s, *self.feet[s][:2].round(9), round(self.feet_yaw[s], 9))
            for s in SIDES
            if self.in_contact[s]
        )
        if key != self._polygon_key:
            self._polygon_key, self._polygon = key, self._compute_polygon()
        return self._polygon

    def _compute_polygon(self) -> np.ndarray:
        corners = [
            sole_corners(
                self.feet[s], self.feet_yaw[s], self.spec.foot_length_m, self.spec.foot_width_m
            )
            for s in SIDES
            if self.in_contact[s]
        ]
        return convex_hull(np.vstack(corners))

    def step(self, command: WalkerCommand) -> MeasuredState:
        # feet follow the walker's targets exactly; a foot in support lands where it is told
        for side in SIDES:  # targets are fresh or immutable arrays: keep references
            target = command.feet[side]
            self.feet[side] = target.position
            self.feet_yaw[side] = target.yaw
            self.in_contact[side] = command.support[side]
        m = self.mass
        # the contact force may only push, along the line from its centre of pressure on the
        # ground to the CoM; the CoP stays inside the support polygon (projected if asked outside)
        f_c = np.asarray(command.contact_force, dtype=float)
        ground = max(self.feet[s][2] for s in SIDES if self.in_contact[s])
        height = max(self.com[2] - ground, 1e-3)
        f_z = max(float(f_c[2]), 1e-6 * m * GRAVITY)  # feet cannot pull
        cop = self.com[:2] - height * f_c[:2] / f_z
        polygon = self.support_polygon()
        xy, self.support_distance = project_to_polygon(cop, polygon)
        self.cop = np.array([xy[0], xy[1], ground])
        # f = k (x − p) with k = f_z / height, i.e. ẍ = (x − c)/β² with β² = m height / f_z and
        # c = p + β² g e_z − β² f_ext / m: the point the CoM is pushed away from (its VRP)
        beta2 = m * height / f_z
        b = math.sqrt(beta2)
        v_c = np.array([xy[0], xy[1], ground]) + beta2 * GRAVITY * E_Z
        # exact solution of ẍ = (x − c(τ))/b² for c(τ) = c0 + ċ τ over the tick (first-order hold
        # of the commanded VRP at the reference's rate, so an undisturbed walk is exactly nominal)
        rate = command.v_cmd_rate if command.v_cmd_rate is not None else np.zeros(3)
        rate = np.array([rate[0], rate[1], 0.0]) if self.support_distance == 0.0 else np.zeros(3)
        c0 = v_c - (b * b / m) * self.external_force()
        dt = self.control_dt
        ch, sh = math.cosh(dt / b), math.sinh(dt / b)
        y, dy = self.com - c0, self.com_velocity - rate
        velocity0 = self.com_velocity
        self.com = c0 + rate * dt + y * ch + b * dy * sh
        self.com_velocity = rate + y * sh / b + dy * ch
        # the contact force actually applied, averaged over the tick (momentum change)
        self.applied = (
            m * (self.com_velocity - velocity0) / dt + m * GRAVITY * E_Z - self.external_force()
        )
        self._ticks += 1
        self.t = self._ticks * dt
        self._check_fall(polygon)
        return self.measure()

    def _check_fall(self, polygon: np.ndarray) -> None:
        xi = self.com + self.b * self.com_velocity  # the robot's own b (nominal CoM height)
        _, d = project_to_polygon(xi[:2], polygon)
        ground = max(self.feet[s][2] for s in SIDES if self.in_contact[s])  # under the stance
        if d > self.spec.max_step_width_m or self.com[2] - ground < 0.5 * self.spec.com_height_m:
            self._fell = True

    # -- state (resume exactly from a tick) and what the feet do -----------------------------
    def get_state(self) -> LipState:
        """A copy of the state: :meth:`set_state` with it continues exactly as this one would."""
        return LipState(
            ticks=self._ticks, com=self.com.copy(), com_velocity=self.com_velocity.copy(),
            feet={s: p.copy() for s, p in self.feet.items()}, feet_yaw=dict(self.feet_yaw),
            in_contact=dict(self.in_contact), applied=self.applied.copy(), cop=self.cop.copy(),
            support_distance=self.support_distance,
            external={b: f.copy() for b, f in self.external.items()}, fell=self._fell,
        )  # fmt: skip

    def set_state(self, state: LipState) -> MeasuredState:
        """Continue from ``state`` (of this robot); returns its measurement."""
        self._ticks = state.ticks
        self.t = state.ticks * self.control_dt
        self.com, self.com_velocity = state.com.copy(), state.com_velocity.copy()
        self.feet = {s: p.copy() for s, p in state.feet.items()}
        self.feet_yaw, self.in_contact = dict(state.feet_yaw), dict(state.in_contact)
        self.applied, self.cop = state.applied.copy(), state.cop.copy()
        self.support_distance = state.support_distance
        self.external = {b: f.copy() for b, f in state.external.items()}
        self._external_sum = sum(self.external.values(), np.zeros(3))
        self._fell = state.fell
        self._polygon_key = None
        return self.measure()

    def physics_state(self) -> np.ndarray:
        """(7,) t, CoM and CoM velocity: the point mass's physical state this tick."""
        return np.concatenate([[self.t], self.com, self.com_velocity])

    def contacts(self) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
        """(centre of pressure m, force N) of each contact: the point mass has one, the force
        its feet push with (along the line from the CoP to the CoM)."""
        return ((self.cop.copy(), self.applied.copy()),)

    def body_position(self, body: str) -> np.ndarray:
        """Every push acts at the CoM of the point mass."""
        return self.com.copy()

    def robot_pose(self) -> None:
        """The point mass has no links."""
        return None
