"""MuJoCo humanoid backend: physics at 1 kHz, state estimation through Pinocchio, terrain, pushes,
falls.

Each control tick (``control_dt``): Pinocchio evaluates the simulated state (CoM, ẋ, soles,
M, h, Jacobians), the whole-body QP (:mod:`dcmviz.sim.wbc`) turns the walker's command into
joint torques, and MuJoCo integrates ``control_dt / physics_dt`` substeps with those torques held.
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass

import mujoco
import numpy as np

from dcmviz import GRAVITY
from dcmviz.gait.terrain import Terrain
from dcmviz.robots import SIDES, Robot
from dcmviz.robots.mujoco_model import FRICTION
from dcmviz.robots.pose import RobotPose
from dcmviz.sim.wbc import Context, ForceObserver, Gains, MomentObserver, WholeBodyController
from dcmviz.walker.state import FootTarget, MeasuredState, WalkerCommand

TERRAIN_FRICTION = FRICTION  # as the floor's
_COS_45 = float(np.cos(np.radians(45.0)))  # a fall: the base tilted more than this

# the clock of ``timings``: wall time; bench/sim.py may set CPU time (time.thread_time)
_clock = time.perf_counter

# what get_state keeps of MuJoCo's data: the whole integration state (time, qpos, qvel, act,
# the solver's warm start, ctrl, applied forces): mj_setState with it, then mj_step, repeats a
# step bit for bit
STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION
# the physical state per tick a shell may keep (time, qpos, qvel, act): 38 numbers for Talos
PHYSICS_SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS


@dataclass(frozen=True)
class MujocoState:
    """Everything the humanoid backend needs to continue exactly from one tick
    (:meth:`MujocoBackend.get_state`): MuJoCo's integration state and what the backend measured
    and estimated at that tick."""

    physics: np.ndarray  # mj_getState(..., STATE_SPEC)
    t: float
    contact: dict[str, bool]
    contact_force: dict[str, float]
    applied: np.ndarray  # (3,) N
    contact_moment: np.ndarray  # (3,) N m
    sole_wrenches: np.ndarray  # (2, 6) cfrc_ext of the soles
    sole_points: np.ndarray  # (2, 3) the point those wrenches are about
    observer: tuple[np.ndarray, np.ndarray, np.ndarray] | None  # L0, integral, estimate
    force_observer: tuple[np.ndarray, np.ndarray, np.ndarray] | None  # p0, integral, estimate
    wbc: tuple  # WholeBodyController.get_state(): held torques, the sustained load's window
    observer_fresh: bool


def terrain_model(robot: Robot, terrain: Terrain) -> mujoco.MjModel:
    """The robot's scene (robot + floor, ``robot.mujoco.spec``) with the terrain's boxes added: each
    a box geom from the floor up to its top face, colliding with the soles like the floor does
    (same contact type, affinity and friction)."""
    spec = robot.mujoco.spec.copy()
    for i, box in enumerate(terrain.boxes):
        centre, half = box.solid
        geom = spec.worldbody.add_geom(
            name=f"terrain_{i}", type=mujoco.mjtGeom.mjGEOM_BOX, size=half.tolist()
        )
        geom.pos = centre.tolist()
        geom.quat = [np.cos(0.5 * box.yaw), 0.0, 0.0, np.sin(0.5 * box.yaw)]
        geom.friction = list(TERRAIN_FRICTION)
        geom.contype, geom.conaffinity = 1, 1
        geom.rgba = [0.62, 0.60, 0.56, 1.0]
    return spec.compile()


class MujocoBackend:
    """A Talos or G1 in MuJoCo, torque-controlled by a whole-body QP.

    With a ``terrain`` its boxes are part of the scene (:func:`terrain_model`), the robot starts
    standing on the ground under its feet and falls are judged above the terrain; without one
    (or a flat one) the scene is the robot's own, unchanged."""

    name = "mujoco"

    def __init__(
        self,
        robot: Robot,
        *,
        control_dt: float = 0.002,
        physics_dt: float = 0.001,
        gains: Gains | None = None,
        terrain: Terrain | None = None,
    ) -> None:
        if not (np.isfinite(control_dt) and control_dt > 0):
            raise ValueError(f"control_dt = {control_dt!r}: must be > 0")
        if not (np.isfinite(physics_dt) and 0 < physics_dt <= control_dt):
            raise ValueError(f"physics_dt = {physics_dt!r}: must be in (0, control_dt]")
        self.robot: Robot = robot
        self.scene = robot.mujoco  # the robot's MuJoCo model (robot, floor, soles, motors)
        self.spec = self.robot.spec
        self.mass = self.robot.mass
        self.control_dt = float(control_dt)
        self.physics_dt = float(physics_dt)
        self.n_substeps = max(1, round(control_dt / physics_dt))
        self.terrain = terrain if terrain is not None else Terrain()
        if self.terrain.flat:
            self.model = copy.deepcopy(self.scene.model)  # own timestep, independent of others
        else:
            self.model = terrain_model(self.robot, self.terrain)
        # ground height (m) under the standing soles at (0, ±spacing/2): the robot starts on it
        half = 0.5 * self.robot.foot_spacing
        self._ground = float(self.terrain.height_at(np.array([[0.0, half], [0.0, -half]])).max())
        self.model.opt.timestep = self.control_dt / self.n_substeps
        self.data = mujoco.MjData(self.model)
        self.wbc = WholeBodyController(self.robot, gains, self.control_dt)
        self.timings = {
            "physics": 0.0,
            "pinocchio": 0.0,
            "qp_build": 0.0,
            "qp_solve": 0.0,
            "other": 0.0,
        }
        self._body_ids = {n: i for i in range(self.model.nbody) if (n := self.model.body(i).name)}
        self._ctx: Context | None = None
        gain = self.wbc.gains.k_moment_observer
        self.moment_observer = MomentObserver(gain) if gain > 0 else None
        self.force_observer = ForceObserver(gain, self.mass, GRAVITY) if gain > 0 else None
        self._observer_fresh = True
        self._contact = {s: False for s in SIDES}
        self._contact_force = {s: 0.0 for s in SIDES}
        self._applied = np.zeros(3)
        # by name: the terrain's geoms come before the robot's in a terrain model
        self._sole_bodies = np.array(
            [self.model.geom_bodyid[self.model.geom(f"{s}_sole").id] for s in SIDES]
        )
        # cfrc_ext is about the subtree CoM of each body's root (the robot's CoM)
        self._sole_roots = self.model.body_rootid[self._sole_bodies]
        self._sole_wrenches = np.zeros((len(SIDES), 6))
        self._sole_points = np.zeros((len(SIDES), 3))
        self._sole_sites = np.array([self.scene.sole_sites[s] for s in SIDES])
        # views into MjData's buffers, fixed for its life: read through them every tick without
        # the bindings' per-access wrapper (the same numbers)
        self._site_z = self.data.site_xpos[:, 2]
        self._body_z = self.data.xpos[:, 2]
        self._cfrc_ext = self.data.cfrc_ext
        self._subtree_com = self.data.subtree_com
        self._qpos_adr = np.asarray(self.scene.qpos_adr, dtype=np.intp)  # robot_pose's joints
        self.t = 0.0
        self._sink = 0.0
        self.reset()
        if self.scene.contact_sink_m is None:
            self.scene.contact_sink_m = self._settled_sink()
        self._sink = self.scene.contact_sink_m
        self.reset()

    def _settled_sink(self, duration: float = 0.3) -> float:
        """How deep (m) the soft sole contacts sink under the robot's weight: stand ``duration``
        s on both feet and read the sole height. Starting that deep avoids a drop at t = 0."""
        state = self.measure()
        weight = np.array([0.0, 0.0, self.mass * GRAVITY])
        zero = np.zeros(3)
        command = WalkerCommand(
            t=0.0,
            support={s: True for s in SIDES},
            feet={s: FootTarget(position=state.feet[s].copy()) for s in SIDES},
            swing_side=None,
            com_force=zero,
            contact_force=weight,
            xi=state.com,
            xi_ref=state.com,
            xi_adj=state.com,
            v_ref=state.com,
            v_cmd=state.com,
            f_hat=zero,
        )
        for _ in range(round(duration / self.control_dt)):
            state = self.step(command)
        return float(max(0.0, self._ground - np.mean([state.feet[s][2] for s in SIDES])))

    # ------------------------------------------------------------------------------------
    def reset(self) -> MeasuredState:
        """Nominal standing posture, soles at (0, ±spacing/2, ground) on the terrain's ground
        there (sunk by the settled contact depth, < 1 mm), zero velocity, no external force,
        t = 0."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:] = self.scene.qpos_mj(self.robot.q_nominal)
        self.data.qpos[2] -= self._sink  # soles as deep as they settle under the weight
        if self._ground:
            self.data.qpos[2] += self._ground  # standing on the terrain under the feet
        self.data.xfrc_applied[:] = 0.0
        mujoco.mj_forward(self.model, self.data)
        self._upper_bodies = np.flatnonzero(self.data.xpos[:, 2] - self._ground > 0.25)
        self.t = 0.0
        self._observer_fresh = True
        self.wbc.reset()
        for k in self.timings:
            self.timings[k] = 0.0
        self._update()
        return self.measure()

    def _update(self) -> Context:
        t0 = _clock()
        d = self.data
        q = self.scene.q_pin(d.qpos)
        v = self.scene.v_pin(d.qpos, d.qvel)
        self._ctx = self.wbc.kinematics.context(q, v)
        t1 = _clock()
        self._measure_contacts()
        if self.moment_observer is not None:
            if self._observer_fresh:
                self.moment_observer.reset(self._ctx.angular_momentum)
                self.force_observer.reset(self._ctx.com_velocity)
                self._observer_fresh = False
            else:
                self.moment_observer.update(
                    self._ctx.angular_momentum, self._contact_moment, self.control_dt
                )
                self.force_observer.update(self._ctx.com_velocity, self._applied, self.control_dt)
            self._ctx.external_moment = self.moment_observer.estimate.copy()
            self._ctx.external_force = self.force_observer.estimate.copy()
        self.timings["pinocchio"] += t1 - t0
        self.timings["other"] += _clock() - t1
        return self._ctx

    def _measure_contacts(self) -> None:
        """Contact wrenches of the soles from MuJoCo (``cfrc_ext`` after ``mj_rnePostConstraint``:
        [τ; f] of each body's external forces about the robot's CoM, world axes): each sole's
        normal force (N) and contact (> 0.1 N), the total contact force (N) and its moment about
        the CoM (N m). Pushes act on other bodies and are not included. A sole body's wrench sums
        its contacts with every geom (the floor and any terrain box), so a sole on a tread counts."""
        mujoco.mj_rnePostConstraint(self.model, self.data)
        wrenches = self._cfrc_ext[self._sole_bodies]
        self._sole_wrenches = wrenches  # (a copy: fancy indexing) for contacts()
        self._sole_points = self._subtree_com[self._sole_roots]
        left, right = wrenches  # the two soles' rows, added: the same sum as over axis 0
        self._applied = left[3:] + right[3:]
        self._contact_moment = left[:3] + right[:3]
        normal = wrenches[:, 5].tolist()
        self._contact_force = dict(zip(SIDES, normal, strict=True))
        self._contact = {s: f > 0.1 for s, f in zip(SIDES, normal, strict=True)}

    def measure(self) -> MeasuredState:
        """CoM, CoM velocity (Pinocchio on the simulated state), sole poses, measured contact.

        ``applied_contact_force`` is the sum of MuJoCo's sole contact forces (world frame, N), the
        force-sensor measurement the observer's eq. (42) uses as the known force."""
        ctx = self._ctx
        feet_yaw = {}
        for s in SIDES:
            r10, r00 = ctx.sole_rotation[s][1::-1, 0].tolist()
            feet_yaw[s] = math.atan2(r10, r00)
        return MeasuredState(
            t=self.t,
            com=ctx.com.copy(),
            com_velocity=ctx.com_velocity.copy(),
            feet={s: ctx.sole_position[s].copy() for s in SIDES},
            feet_yaw=feet_yaw,
            in_contact=dict(self._contact),
            mass=self.mass,
            applied_contact_force=self._applied.copy(),
            external_moment=self.wbc.sustained.moment.copy(),
        )

    def step(self, command: WalkerCommand) -> MeasuredState:
        """One control period: whole-body QP → torques → physics substeps → measurement."""
        ctx = self._ctx
        sol = self.wbc.solve(ctx, command, self._contact)
        self.data.ctrl[:] = sol.tau
        t0 = _clock()
        for _ in range(self.n_substeps):
            mujoco.mj_step(self.model, self.data)
        self.timings["physics"] += _clock() - t0
        self.timings["qp_build"] = self.wbc.timings["qp_build"]
        self.timings["qp_solve"] = self.wbc.timings["qp_solve"]
        self.t += self.control_dt
        self._update()
        return self.measure()

    # ------------------------------------------------------------------------------------
    def _body_id(self, body: str) -> int:
        link = self.spec.bodies.get(body, body)
        if link not in self._body_ids or link == "world":
            allowed = ", ".join(list(self.spec.bodies) + ["or a link name"])
            raise ValueError(f"body {body!r}: unknown body of {self.spec.name}; allowed: {allowed}")
        return self._body_ids[link]

    def set_external_force(self, body: str, force: np.ndarray) -> None:
        """Persistent world-frame force (N) at the CoM of ``body`` (alias or link name)."""
        f = np.asarray(force, dtype=float)
        if f.shape != (3,) or not np.all(np.isfinite(f)):
            raise ValueError(f"force = {force!r}: must be 3 finite numbers (N)")
        bid = self._body_id(body)
        self.data.xfrc_applied[bid, :3] = f
        self.data.xfrc_applied[bid, 3:] = 0.0

    def clear_external_forces(self) -> None:
        """Remove every external force."""
        self.data.xfrc_applied[:] = 0.0

    def fell(self) -> bool:
        """Base below 55 % of its nominal height above the soles, tilted more than 45°, or a
        body that stands ≥ 0.25 m high in the nominal posture (knee, hip, torso, arm) within
        0.08 m of the floor under the soles (only the soles collide, so this stands in for a
        non-foot contact). On terrain, heights are taken above the ground under the base and
        under each of those bodies instead of the lower sole."""
        d = self.data
        if not self.terrain.flat:
            return self._fell_on_terrain()
        floor = self._site_z[self._sole_sites].min()
        base_z = d.qpos[2] - floor
        nominal = self.robot.q_nominal[2]
        up = d.xmat[1][8]  # cos(tilt) of the root body
        low = self._body_z[self._upper_bodies].min() - floor < 0.08
        return bool(base_z < 0.55 * nominal or up < _COS_45 or low)

    def _fell_on_terrain(self) -> bool:
        d = self.data
        base_z = d.qpos[2] - float(self.terrain.height_at(d.qpos[:2]))
        up = d.xmat[1][8]
        bodies = d.xpos[self._upper_bodies]
        low = bool(np.any(bodies[:, 2] - self.terrain.height_at(bodies[:, :2]) < 0.08))
        nominal = self.robot.q_nominal[2]
        return bool(base_z < 0.55 * nominal or up < _COS_45 or low)

    # --- state (resume exactly from a tick) ------------------------------------------------
    def get_state(self) -> MujocoState:
        """A copy of the state: :meth:`set_state` with it continues bit for bit as this backend
        would (MuJoCo's integration state, the measured contacts, the moment and force
        observers, the sustained load's window, the whole-body QP's held torques)."""
        physics = np.empty(mujoco.mj_stateSize(self.model, STATE_SPEC))
        mujoco.mj_getState(self.model, self.data, physics, STATE_SPEC)
        obs, fobs = self.moment_observer, self.force_observer
        return MujocoState(
            physics=physics, t=self.t, contact=dict(self._contact),
            contact_force=dict(self._contact_force), applied=self._applied.copy(),
            contact_moment=self._contact_moment.copy(),
            sole_wrenches=self._sole_wrenches.copy(), sole_points=self._sole_points.copy(),
            observer=None if obs is None else (obs.L0.copy(), obs.integral.copy(),
                                               obs.estimate.copy()),
            force_observer=None if fobs is None else (fobs.p0.copy(), fobs.integral.copy(),
                                                      fobs.estimate.copy()),
            wbc=self.wbc.get_state(),
            observer_fresh=self._observer_fresh,
        )  # fmt: skip

    def set_state(self, state: MujocoState) -> MeasuredState:
        """Continue from ``state`` (of this model); returns its measurement."""
        mujoco.mj_setState(self.model, self.data, state.physics, STATE_SPEC)
        mujoco.mj_forward(self.model, self.data)  # body positions (drawing, falls) of the state
        self.t = state.t
        self._contact, self._contact_force = dict(state.contact), dict(state.contact_force)
        self._applied, self._contact_moment = state.applied.copy(), state.contact_moment.copy()
        self._sole_wrenches = state.sole_wrenches.copy()
        self._sole_points = state.sole_points.copy()
        if self.moment_observer is not None and state.observer is not None:
            obs = self.moment_observer
            obs.L0, obs.integral, obs.estimate = (a.copy() for a in state.observer)
        if self.force_observer is not None and state.force_observer is not None:
            fobs = self.force_observer
            fobs.p0, fobs.integral, fobs.estimate = (a.copy() for a in state.force_observer)
        self.wbc.set_state(state.wbc)
        self._observer_fresh = state.observer_fresh
        d = self.data
        self._ctx = self.wbc.kinematics.context(
            self.scene.q_pin(d.qpos), self.scene.v_pin(d.qpos, d.qvel)
        )
        if self.moment_observer is not None:
            self._ctx.external_moment = self.moment_observer.estimate.copy()
            self._ctx.external_force = self.force_observer.estimate.copy()
        return self.measure()

    def physics_state(self) -> np.ndarray:
        """MuJoCo's physical state this tick (mjSTATE_FULLPHYSICS: time, qpos, qvel, act)."""
        out = np.empty(mujoco.mj_stateSize(self.model, PHYSICS_SPEC))
        mujoco.mj_getState(self.model, self.data, out, PHYSICS_SPEC)
        return out

    def contacts(self) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
        """(centre of pressure m, force N) of each sole in contact, from MuJoCo's contact
        wrench on the sole (cfrc_ext, about the robot's CoM): the point on the sole's plane
        about which the contact moment has no horizontal part."""
        out = []
        for i, side in enumerate(SIDES):
            f, tau = self._sole_wrenches[i, 3:], self._sole_wrenches[i, :3]
            if not self._contact[side] or f[2] <= 1e-6:
                continue
            c = self._sole_points[i]
            z = self._ctx.sole_position[side][2] if self._ctx is not None else 0.0
            rz = c[2] - z
            cop = np.array([c[0] - (tau[1] + rz * f[0]) / f[2],
                            c[1] + (tau[0] - rz * f[1]) / f[2], z])  # fmt: skip
            out.append((cop, f.copy()))
        return tuple(out)

    # --- drawing / recording -------------------------------------------------------------
    def qpos_by_joint(self) -> dict[str, float]:
        """Angle (rad) of every URDF joint: the simulated legs and the locked upper body."""
        angles = dict(self.robot.locked_joints)
        joints = self.robot.joint_names
        angles.update(zip(joints, self.data.qpos[self._qpos_adr].tolist(), strict=True))
        return angles

    def robot_pose(self) -> RobotPose:
        """Floating base and every URDF joint angle (for drawing and recording)."""
        position, wxyz = self.base_pose()
        return RobotPose(position, wxyz, self.qpos_by_joint())

    def body_position(self, body: str) -> np.ndarray:
        """World position (m) of the link a push on ``body`` acts on."""
        return self.data.xpos[self._body_id(body)].copy()

    def base_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Base position (m) and orientation quaternion (w, x, y, z)."""
        return self.data.qpos[:3].copy(), self.data.qpos[3:7].copy()

    def body_poses(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Every named body: world position (m) and quaternion (w, x, y, z)."""
        d = self.data
        return {n: (d.xpos[i].copy(), d.xquat[i].copy()) for n, i in self._body_ids.items()}

    @property
    def external_moment(self) -> np.ndarray:
        """Estimated external moment about the CoM (N m, world), :class:`MomentObserver`.

        The feet counter it by moving the CoP by δ = (τ̂_y, -τ̂_x)/f_z from the VRP. A walker that
        shifts its VRP and DCM references by (-τ̂_y, τ̂_x, 0)/(m g) on top of eqs. (47)–(49) keeps
        the CoP where it planned it (tested: the 15 % torso tug of war then holds through the
        pull). Not part of the backend interface (MeasuredState) yet."""
        return self._ctx.external_moment.copy()

    @property
    def contact_forces(self) -> dict[str, float]:
        """Measured normal force under each sole, N."""
        return dict(self._contact_force)
