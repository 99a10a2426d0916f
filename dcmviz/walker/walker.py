"""The per-tick loop of §III, the same for every backend.

Each tick the walker reads a :class:`~dcmviz.walker.state.MeasuredState` and answers a
:class:`~dcmviz.walker.state.WalkerCommand`:

1. clock the walk through its plan (:meth:`dcmviz.gait.walk.Walk.clock`): footsteps are
   committed where the feet land, continuous mode replans at each touchdown;
2. measured DCM ξ = x + b ẋ (eq. 1);
3. disturbance observer F̂ (eqs. 45, 46) and the reference shift s = −b²/m F̂ (eqs. 47–49),
   v_ref shifted by s − b ṡ where s changes (:class:`~dcmviz.dcm.observer.ShiftRate`);
4. push recovery by the strategy of ``control.recovery`` (:mod:`dcmviz.recovery`): which
   footsteps move where, and the adapted DCM reference ξ_adj = ξ_ref + Δξ_adj (eqs. 27–35);
5. desired VRP v = v_ref + (1 + k_ξ b)(ξ − ξ_adj) (eq. 41; eq. 24 without adjustment) and the CoM
   force F = m/b² (x − v) (eq. 4); the feet must push with F + m g e_z − F̂;
6. foot targets: stance feet where they stand, the swing foot on a C² path re-targeted to the
   adjusted footstep.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence

import numpy as np

from dcmviz import GRAVITY
from dcmviz.config import Config, ControlSection
from dcmviz.dcm import DisturbanceObserver, ShiftRate, moment_shift, reference_shift
from dcmviz.dcm.sustained import SustainedLoad
from dcmviz.gait import GaitPlan, Planner
from dcmviz.gait.height import walk_height_m
from dcmviz.gait.terrain import Terrain, terrain_of
from dcmviz.gait.walk import Walk
from dcmviz.recovery import NO_ADJUSTMENT, Adjustment, RecoveryStrategy, make_strategy
from dcmviz.robots import SIDES, Robot
from dcmviz.robots.feet import Footstep
from dcmviz.robots.gains import Gains
from dcmviz.walker.state import FootTarget, MeasuredState, WalkerCommand, WalkerStatus

E_Z = np.array([0.0, 0.0, 1.0])
_NO_MOMENT = np.zeros(3)
_NO_MOMENT.flags.writeable = False
_ZERO = np.zeros(3)  # a standing foot's velocity and acceleration (shared: read-only)
_ZERO.flags.writeable = False


class Walker:
    """Backend-independent DCM walking controller (§III) for one preset and one robot (its
    planning facts and, for the crossover strategy, its kinematics)."""

    def __init__(
        self,
        config: Config,
        robot: Robot,
        *,
        mass: float,
        dt: float,
        terrain: Terrain | None = None,
        plan_version: int = 0,
    ) -> None:
        """``terrain``: the preset's (default: built from ``config.terrain``); ``plan_version``:
        where the count of plans starts (a session's walks keep counting)."""
        self.config = config
        self.control: ControlSection = config.control  # gains: may change while walking
        self.robot = robot
        self.spec = spec = robot.spec
        self.terrain = terrain if terrain is not None else terrain_of(config.terrain)
        self.planner = Planner(config.gait, config.dcm, spec, self.terrain)
        self.mass = float(mass)
        self._weight_xyz = (0.0, 0.0, self.mass * GRAVITY)  # m g e_z (N), once (floats)
        self.dt = float(dt)
        self.b = config.dcm.b
        self.observer = DisturbanceObserver(self.mass, config.control.k_f)
        self.shift_rate = ShiftRate(self.dt)  # ṡ: v_ref + s − b ṡ (ShiftRate)
        # the part of F̂ that has lasted (a pull, not a push), for a strategy that plans ahead
        # with it (RecoveryStrategy.uses_held_load): the whole-body QP's notion of held, with
        # its window and lag
        gains = Gains.for_robot(robot)
        self.held = SustainedLoad(gains.sustained_time_s, self.dt, gains.sustained_settle_s)
        self.walk: Walk | None = None
        self._first_version = plan_version
        self._adjustment: Adjustment = NO_ADJUSTMENT
        self._status: WalkerStatus | None = None
        # per side: the footstep a foot stands on and its target (_standing_target)
        self._standing: dict[str, tuple[Footstep, FootTarget]] = {}
        # H(0) of the legs (gait.height.walk_height_m), the reach at no lean (_lean_height)
        self._reach_upright = walk_height_m(spec, 0.0)

    def set_config(self, config: Config, state: MeasuredState) -> None:
        """Adopt a preset that differs from the walked one in its ``[control]`` section only,
        from the next tick on, without restarting the walk.

        k_ξ, step adjustment on/off and its limit act on the next command; k_F changes the
        observer's rate; an observer switched on starts from the present momentum (eq. 43), so
        F̂ starts at zero instead of jumping; another ``control.recovery`` takes over with a
        fresh state from the next tick.
        """
        control = config.control
        if control.observer != self.control.observer:
            self.shift_rate.reset()  # the shift starts (F̂ from 0) or is dropped: no rate
        if control.observer and not self.control.observer:
            self.observer.reset(state.com_velocity)
        self.observer.k_f = float(control.k_f)
        if control.recovery != self.control.recovery:
            self.strategy = self._strategy(control)
            self.held.reset()  # fed only for a strategy that uses it
        self.config = config
        self.control = control

    def _strategy(self, control: ControlSection) -> RecoveryStrategy:
        return make_strategy(control.recovery, self.robot, self.terrain, self.b, self.dt)

    # -- lifecycle ------------------------------------------------------------------------------
    def reset(self, state: MeasuredState) -> GaitPlan:
        """Start standing where the backend's feet are; returns the nominal plan."""
        version = self.walk.plan_version if self.walk is not None else self._first_version
        self.walk = Walk(
            self.planner, state.feet, state.feet_yaw, t0=state.t, com=state.com,
            plan_version=version,
        )  # fmt: skip
        self.strategy = self._strategy(self.control)
        self._adjustment = NO_ADJUSTMENT
        self._last_contact_force = self.mass * GRAVITY * E_Z
        self._standing = {}
        self.observer.reset(state.com_velocity)
        self.shift_rate.reset()
        self.held.reset()
        self._status = None
        return self.walk.plan

    # -- one tick -------------------------------------------------------------------------------
    def step(self, state: MeasuredState) -> WalkerCommand:
        """One tick of §III.  The 3-vectors are worked per component in floats (numpy's
        per-call overhead would be most of their cost), with the same operations in the same
        order as the equations' vector forms cited; arrays are built for what is handed on."""
        if self.walk is None:
            self.reset(state)
        walk = self.walk
        t = state.t
        cfg = self.control
        m, b = self.mass, self.b
        self._status = None

        contact, touched = walk.clock(t, state.feet, state.feet_yaw)

        # observer, eqs. (45), (46); the known force is the contact force plus gravity
        known = state.applied_contact_force
        if known is None:
            known = self._last_contact_force
        if cfg.observer:
            kx, ky, kz = np.asarray(known, float).tolist()
            gx, gy, gz = self._weight_xyz
            f_hat = self.observer.update(state.com_velocity, (kx - gx, ky - gy, kz - gz), self.dt)
            fx, fy, fz = f_hat.tolist()
            c = -(b * b / m)  # s = −b²/m F̂, eqs. (47)–(49) (reference_shift)
            sx, sy, sz = c * fx, c * fy, c * fz
            if state.external_moment is not None:  # (−τ̂_y, τ̂_x, 0)/(m g) (moment_shift)
                tx, ty, _ = np.asarray(state.external_moment, float).tolist()
                mg = m * GRAVITY
                sx, sy, sz = sx + -ty / mg, sy + tx / mg, sz + 0.0
        else:
            f_hat = np.zeros(3)
            fx = fy = fz = sx = sy = sz = 0.0
        preview = walk.plan.preview
        local = t - walk.plan.t0
        # the plan's VRP, DCM and VRP rate now (clamped to the plan's span)
        v_plan, xi_plan, v_rate = preview.references(local)
        if cfg.observer:
            height = self._planned_height(v_plan, contact.swing_side)
            sx, sy, sz = self._lean_height((sx, sy, sz), height)
        shift = np.array((sx, sy, sz))  # as the strategies take it
        com_x, com_y, com_z = state.com.tolist()
        vel_x, vel_y, vel_z = state.com_velocity.tolist()
        xi_x, xi_y, xi_z = com_x + b * vel_x, com_y + b * vel_y, com_z + b * vel_z  # eq. (1)
        xi = np.array((xi_x, xi_y, xi_z))
        held = None
        if self.strategy.uses_held_load:
            held = np.zeros(3)
            if cfg.observer:  # the shift of the load expected to last: F̂ held for a second
                self.held.update(t, f_hat, _NO_MOMENT)
                held = reference_shift(self.held.force, m, b)
                if state.external_moment is not None:  # (the backend's held moment)
                    held = held + moment_shift(state.external_moment, m)
        if cfg.step_adjustment and not touched:  # a strategy may re-time the walk first
            plan = self.strategy.retime(walk, t, xi, shift, cfg.max_step_adjustment, held=held)
            if plan is not None:
                walk.retime(t, plan)
                # a re-timed swing may end (or a double support give way to a swing) now: commit
                # the touchdown where the foot is, as the clock does.  Read off the plan alone,
                # the foot was told to stand where it had lifted off for a tick, and the point
                # mass put its footstep there (a G1 pushed at 2x stepped back 0.3 m)
                contact, touched = walk.clock(t, state.feet, state.feet_yaw)

        if walk.plan.preview is not preview:  # re-timed: the same time in the new plan
            preview = walk.plan.preview
            local = t - walk.plan.t0
            v_plan, xi_plan, v_rate = preview.references(local)
        if local >= preview.duration:  # the plan has ended: stand on its final VRP (D3)
            v_plan = xi_plan = preview.waypoints[-1].tolist()
            v_rate = (0.0, 0.0, 0.0)
        ref_x, ref_y, ref_z = xi_plan[0] + sx, xi_plan[1] + sy, xi_plan[2] + sz  # eq. (48)
        vr_x, vr_y, vr_z = v_plan[0] + sx, v_plan[1] + sy, v_plan[2] + sz  # eq. (47)
        if cfg.observer:  # a shift that changes: the VRP of the shifted ξ_ref (ShiftRate)
            rx, ry, rz = self.shift_rate.update_floats(sx, sy, sz)
            vr_x, vr_y, vr_z = vr_x - b * rx, vr_y - b * ry, vr_z - b * rz
        xi_ref = np.array((ref_x, ref_y, ref_z))
        if cfg.step_adjustment:  # push recovery (§III-A)
            adjustment = self.strategy.adjust(walk, t, local, xi - xi_ref, cfg.max_step_adjustment)
            if adjustment.retarget_swing:
                walk.retarget_swing(t, adjustment.target[1])
            dx, dy, dz = adjustment.delta.tolist()
            adj_x, adj_y, adj_z = ref_x + dx, ref_y + dy, ref_z + dz  # eqs. (33), (49)
            xi_adj = np.array((adj_x, adj_y, adj_z))
        else:
            adjustment, xi_adj = NO_ADJUSTMENT, xi_ref
            adj_x, adj_y, adj_z = ref_x, ref_y, ref_z
        self._adjustment = adjustment

        # v = v_ref + (1 + k_ξ b)(ξ − ξ_adj), eq. (41) (eq. 24 if ξ_adj = ξ_ref; vrp_tracking)
        k = 1.0 + cfg.k_xi * b
        v_cmd = np.array(
            (vr_x + k * (xi_x - adj_x), vr_y + k * (xi_y - adj_y), vr_z + k * (xi_z - adj_z))
        )
        if cfg.step_adjustment:
            v_cmd = self.strategy.shape_vrp(v_cmd, contact.support, walk.placed, shift)
        vx, vy, vz = v_cmd.tolist()
        g = m / (b * b)  # F = m/b² (x − v), eq. (4) (com_force)
        force_x, force_y, force_z = g * (com_x - vx), g * (com_y - vy), g * (com_z - vz)
        gx, gy, gz = self._weight_xyz  # the feet push with F + m g e_z − F̂
        contact_force = np.array((force_x + gx - fx, force_y + gy - fy, force_z + gz - fz))
        self._last_contact_force = contact_force

        feet = {}
        for side in SIDES:
            if side == contact.swing_side and walk.swing is not None:
                p, v, a, yaw, yaw_rate = walk.swing.sample(t)
                feet[side] = FootTarget(p, v, a, yaw, yaw_rate)
            else:
                feet[side] = self._standing_target(walk.placed[side])

        return WalkerCommand(
            t=t,
            support=contact.support,
            feet=feet,
            swing_side=contact.swing_side,
            com_force=np.array((force_x, force_y, force_z)),
            contact_force=contact_force,
            xi=xi,
            xi_ref=xi_ref,
            xi_adj=xi_adj,
            v_ref=np.array((vr_x, vr_y, vr_z)),
            v_cmd=v_cmd,
            f_hat=f_hat,
            v_cmd_rate=np.array(v_rate),
            phase=contact.phase,
            swing_progress=contact.swing_progress,
            step_index=walk.steps_completed,
            done=walk.done(t),
            legs_may_cross=self.strategy.crosses_legs,
        )

    def _standing_target(self, placed: Footstep) -> FootTarget:
        """The target of a foot that stands at ``placed``: the same object for every tick it
        stands there (its arrays read-only)."""
        cached = self._standing.get(placed.side)
        if cached is None or cached[0] is not placed:
            target = FootTarget(placed.position, _ZERO, _ZERO, placed.yaw)
            self._standing[placed.side] = cached = (placed, target)
        return cached[1]

    def copy(self) -> Walker:
        """An independent copy that continues exactly as this walker would from its last tick
        (walk, observer, strategy, last command); what never changes is shared: the robot's
        facts, the terrain, the planner, the settings and the plans (frozen)."""
        shared = [self.robot, self.spec, self.terrain, self.planner, self.config, self.control]
        walk = self.walk
        if walk is not None:
            shared += [walk.plan, walk.nominal_plan, walk.records, walk.planner]
        return copy.deepcopy(self, {id(x): x for x in shared})

    def _planned_height(self, v_plan: Sequence[float], swing_side: str | None) -> float:
        """The plan's VRP height (m) now (``v_plan``, the plan's VRP at this tick) above the
        foot whose leg reaches furthest: the stance foot in single support, the lower foot in
        double support.  The plan has already lowered it where the stride spans the legs
        (:func:`dcmviz.gait.height.step_heights`)."""
        ground = min(float(f.position[2]) for s, f in self.walk.placed.items() if s != swing_side)
        return float(v_plan[2]) - ground

    def _lean_height(self, shift: Sequence[float], height: float) -> Sequence[float]:
        """The reference shift with the CoM lowered where leaning away from a sustained force
        asks more of the legs than they reach at the plan's ``height``: each leg spans the lean
        s = |shift_xy| from hip to ankle (:func:`dcmviz.gait.height.walk_height_m`), and the
        whole robot leaning by atan(s/height) (the humanoid's trunk does) lifts the hip on the far
        side by half the foot spacing times its sine: the CoM comes down to what the legs then
        reach, from the height the plan already asks for (lowering from b's nominal height
        instead counted the plan's own lowering twice: Romeo's knees, 38 N m for 40 kg, gave way
        under a 5 % pull at 12 mm below its walking height).  ``shift`` as given, or a new
        (x, y, z) in floats."""
        lean = math.hypot(float(shift[0]), float(shift[1]))
        spec = self.spec
        if lean <= 0.0 or spec.leg_length_m is None:
            return shift
        hip_rise = 0.5 * spec.foot_spacing_m * math.sin(math.atan2(lean, height))
        reach = spec.max_com_height_m + walk_height_m(spec, lean) - self._reach_upright
        # from the height the plan asks for, but no more than the legs reach standing (a start
        # from a higher standing posture): the lowering is what the lean adds, 0 at no lean
        drop = min(0.0, reach - hip_rise - min(height, spec.max_com_height_m))
        if drop >= 0.0:
            return shift
        return (shift[0], shift[1], shift[2] + drop)

    # -- what the walker publishes --------------------------------------------------------------
    @property
    def status(self) -> WalkerStatus:
        """The walk after the last tick, frozen (built once per tick, on request)."""
        if self._status is None:
            walk, adjustment = self.walk, self._adjustment
            self._status = WalkerStatus(
                plan=walk.plan,
                plan_version=walk.plan_version,
                nominal_plan=walk.nominal_plan,
                adjusted=adjustment.target,
                following=adjustment.following,
                records=walk.records,
                steps_completed=walk.steps_completed,
                next_step_index=walk.next_step_index,
                swing_path=walk.swing.path if walk.swing is not None else None,
            )
        return self._status

    @property
    def plan(self) -> GaitPlan:
        """The plan walked now (with committed adjustments; continuous: the horizon)."""
        return self.walk.plan

    @property
    def steps_completed(self) -> int:
        return self.walk.steps_completed

    @property
    def step_adjustments(self) -> list[dict[str, float]]:
        """Committed footsteps that landed away from the nominal plan: {t, step, dx, dy} (m)."""
        return self.walk.step_adjustments
