"""The per-tick loop of §III, the same for every backend.

Each tick the walker reads a :class:`~dcmviz.state.MeasuredState` and answers a
:class:`~dcmviz.state.WalkerCommand`:

1. clock through the plan; at a touchdown commit the footstep where the foot really landed
   (``GaitPlan.with_step``: only that footstep's waypoints move, so no reference jumps, eqs. 27, 34);
   in continuous mode replan the next steps from there (receding horizon);
2. measured DCM ξ = x + b ẋ (eq. 1);
3. disturbance observer F̂ (eqs. 45, 46) and the reference shift −b²/m F̂ (eqs. 47–49);
4. step adjustment of the next modifiable footstep Δv_adj = A_adj ξ̃ (eq. 32), horizontal, limited
   to the reach, and the adapted DCM reference ξ_adj = ξ_ref + Δξ_adj (eqs. 33–35);
5. desired VRP v = v_ref + (1 + k_ξ b)(ξ − ξ_adj) (eq. 41; eq. 24 without adjustment) and the CoM
   force F = m/b² (x − v) (eq. 4); the feet must push with F + m g e_z − F̂;
6. foot targets: stance feet where they stand, the swing foot on a C² path re-targeted to the
   adjusted footstep.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dcmviz import GRAVITY, recovery
from dcmviz.config import Config, ControlSection
from dcmviz.dcm import (
    DisturbanceObserver,
    adjustment_gain,
    com_force,
    dcm_adjustment,
    moment_shift,
    reference_shift,
    vrp_tracking,
)
from dcmviz.gait import (
    OTHER,
    Footstep,
    GaitPlan,
    SwingTrajectory,
    build_plan,
    clamp_to_reach,
    horizon_steps,
    on_terrain,
    plan_footsteps,
    timing,
    timing_of,
)
from dcmviz.recovery import Candidate
from dcmviz.robots import get_spec
from dcmviz.robots.geometry import convex_hull, project_to_polygon, sole_corners
from dcmviz.state import SIDES, FootTarget, MeasuredState, WalkerCommand
from dcmviz.terrain import EDGE_MARGIN_M, terrain_of

MULTI_STEPS = 3  # footsteps sharing the DCM error with recovery = "multi_step"
CAPACITY_MARGIN_M = 0.01  # the recovery QP's CoP stays this far inside the soles
CAPACITY_TIME_CONSTANTS = 1.0  # τ/b: the CoP is credited with removing ε within one b
QUIET_SLACK_M = 1e-4  # m: below this shortfall a nominal timing is not questioned
RETIME_PERIOD_S = 0.03  # s between comparisons of candidate timings (multi_step_timing)
STEP_COST_WEIGHT = 1e-3  # timing score: Σ ω |Δv|² (m²) against σ² (m²) ...
TIMING_COST_WEIGHT = 1e-3  # ... and Σ (T − T_nominal)² (s²)
CAPTURE_WEIGHT = 1.0  # timing score: the capture shortfall² (m²) against σ² (m²)
LATERAL_PRIORITY = 4.0  # a VRP outside the support keeps its lateral part first (_inside_support)
PRIORITY_BLEND_M = 0.03  # ... blended in over this far beyond the outer foot
TIMING_HYSTERESIS = 0.8  # a new target timing must score below this fraction of the kept one
HORIZON_STEPS = 4  # continuous mode: at least this many footsteps previewed ahead
HORIZON_TIME_CONSTANTS = 15.0  # ... and at least 15 b of walking before the terminal constraint
RECORDS_KEPT = 256  # continuous mode: landed footsteps kept (a plan keeps all of its own)


def horizon_count(gait, b: float) -> int:
    """Footsteps in the continuous mode's receding horizon.

    The terminal constraint (eq. 17) at the horizon's end, and the footstep each replanning
    adds there, reach back to the present through e^(−T_h/b) (eq. 15); with T_h ≥ 15 b that is
    below 1e-6, so a replanning moves ξ_ref by less than 1e-6 of a step instead of millimetres
    to centimetres with a fixed count of 4 steps (fast steps, large b).
    """
    per_step = gait.t_ss + gait.t_ds
    return max(HORIZON_STEPS, math.ceil(HORIZON_TIME_CONSTANTS * b / per_step))


E_Z = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class StepRecord:
    """A committed footstep: where it landed relative to the nominal plan."""

    t: float  # s, touchdown
    step: int  # footstep counter since the start
    side: str
    position: np.ndarray  # (3,) where it landed
    nominal: np.ndarray  # (3,) where the nominal plan had it

    @property
    def adjustment(self) -> np.ndarray:
        return self.position - self.nominal


class Walker:
    """Backend-independent DCM walking controller (§III) for one preset."""

    def __init__(self, config: Config, *, mass: float, dt: float) -> None:
        self.config = config
        self.control: ControlSection = config.control  # gains: may change while walking
        self.spec = get_spec(config.robot.model)
        self.terrain = terrain_of(config.terrain)
        self.mass = float(mass)
        self._weight = self.mass * GRAVITY * E_Z  # m g e_z (N), once instead of twice a tick
        self.dt = float(dt)
        self.b = config.dcm.b
        self.observer = DisturbanceObserver(self.mass, config.control.k_f)
        self.plan: GaitPlan | None = None
        self.plan_version = 0  # changes whenever self.plan does
        self._gains: dict[tuple[int, int], float] = {}  # A_adj per (plan_version, footstep)

    def set_control(self, control: ControlSection, state: MeasuredState) -> None:
        """Adopt new gains from the next tick on, without restarting the walk.

        k_ξ, step adjustment on/off and its limit act on the next command; k_F changes the
        observer's rate; an observer switched on starts from the present momentum (eq. 43), so
        F̂ starts at zero instead of jumping.
        """
        if control.observer and not self.control.observer:
            self.observer.reset(state.com_velocity)
        self.observer.k_f = float(control.k_f)
        self.control = control

    # -- lifecycle ------------------------------------------------------------------------------
    def reset(self, state: MeasuredState) -> GaitPlan:
        """Start standing where the backend's feet are; returns the nominal plan."""
        gait = self.config.gait
        start = {
            s: Footstep(s, np.array(state.feet[s], float), float(state.feet_yaw[s])) for s in SIDES
        }
        if gait.mode == "plan":
            _, steps = plan_footsteps(gait)
        else:
            steps = horizon_steps(gait, start, gait.first_swing, horizon_count(gait, self.b))
        steps = on_terrain(steps, self.terrain)
        self.plan = build_plan(
            start,
            steps,
            timing_of(gait),
            self.b,
            self.config.dcm.order,
            t0=state.t,
            start_com=state.com,
            spec=self.spec,
        )
        self.plan_version += 1
        self.nominal_plan = self.plan
        self._nominal_durations = self.plan.preview.durations.copy()  # before any re-timing
        self._timing_target: np.ndarray | None = None
        self._retime_tick = 0
        self._last_slack = 0.0  # m, the recovery QP's CoP shortfall at the last tick
        self.placed: dict[str, Footstep] = dict(start)  # where each foot stands (committed)
        self._nominal_feet: dict[str, Footstep] = dict(start)  # continuous mode: nominal cursor
        self.swing: SwingTrajectory | None = None
        self.swing_step: int | None = None
        self.adjusted_target: tuple[int, np.ndarray] | None = None  # (step, position) pending
        self.recovery_target: tuple[int, np.ndarray] | None = None  # the footstep after it
        # grows at touchdowns (continuous mode: the last RECORDS_KEPT); shared by every Tick
        self.records: tuple[StepRecord, ...] = ()
        self.steps_completed = 0
        self._last_contact_force = self.mass * GRAVITY * E_Z
        self.observer.reset(state.com_velocity)
        return self.plan

    # -- one tick -------------------------------------------------------------------------------
    def step(self, state: MeasuredState) -> WalkerCommand:
        if self.plan is None:
            self.reset(state)
        t = state.t
        cfg = self.control
        m, b = self.mass, self.b

        contact = self.plan.contact(t)
        touched = False
        if self.swing_step is not None and not (
            contact.kind == "ss" and contact.step == self.swing_step
        ):
            self._touchdown(state)
            contact = self.plan.contact(t)
            touched = True
        if contact.kind == "ss" and self.swing_step != contact.step:
            self._liftoff(state, contact.step)

        # observer, eqs. (45), (46); the known force is the contact force plus gravity
        known = state.applied_contact_force
        if known is None:
            known = self._last_contact_force
        if cfg.observer:
            f_hat = self.observer.update(state.com_velocity, known - self._weight, self.dt)
        else:
            f_hat = np.zeros(3)
        shift = reference_shift(f_hat, m, b) if cfg.observer else np.zeros(3)
        if cfg.observer and state.external_moment is not None:
            shift = shift + moment_shift(state.external_moment, m)
        # -- step timing (issue 11): re-time the plan before its references are read ----------
        if cfg.step_adjustment and cfg.recovery == "multi_step_timing" and not touched:
            if self._retime(t, state.dcm(b), shift):
                contact = self.plan.contact(t)
        # -------------------------------------------------------------------------------------

        preview = self.plan.preview
        local = t - self.plan.t0
        xi_ref = preview.dcm(local) + shift  # eq. (48)
        v_ref = preview.vrp(local) + shift  # eq. (47)
        xi = state.dcm(b)

        if local >= preview.duration:  # the plan has ended: stand on its final VRP (D3)
            xi_ref = v_ref = preview.waypoints[-1] + shift
        xi_adj = xi_ref + self._adjust(t, local, xi - xi_ref) if cfg.step_adjustment else xi_ref
        if not cfg.step_adjustment:
            self.adjusted_target, self.recovery_target = None, None

        v_cmd = vrp_tracking(v_ref, xi, xi_adj, cfg.k_xi, b)  # eq. (41) (eq. 24 if ξ_adj = ξ_ref)
        if cfg.step_adjustment and cfg.recovery != "next_step":  # issue 11: keep the lateral CoP
            v_cmd = self._inside_support(v_cmd, contact.support)
        force = com_force(state.com, v_cmd, m, b)  # eq. (4)
        contact_force = force + self._weight - f_hat
        self._last_contact_force = contact_force

        feet = {}
        for side in SIDES:
            if side == contact.swing_side and self.swing is not None:
                p, v, a, yaw, yaw_rate = self.swing.sample(t)
                feet[side] = FootTarget(p, v, a, yaw, yaw_rate)
            else:
                placed = self.placed[side]
                feet[side] = FootTarget(placed.position, yaw=placed.yaw)

        return WalkerCommand(
            t=t,
            support=contact.support,
            feet=feet,
            swing_side=contact.swing_side,
            com_force=force,
            contact_force=contact_force,
            xi=xi,
            xi_ref=xi_ref,
            xi_adj=xi_adj,
            v_ref=v_ref,
            v_cmd=v_cmd,
            f_hat=f_hat,
            v_cmd_rate=preview.vrp_velocity(local) if local < preview.duration else np.zeros(3),
            phase=contact.phase,
            step_index=self.steps_completed,
            done=self.done(t),
        )

    def _adjust(self, t: float, local: float, xi_error: np.ndarray) -> np.ndarray:
        """Δξ_adj of eqs. (33)–(35), (49) for the DCM error ξ̃ = ξ − ξ_ref, re-targeting the swing.

        The next modifiable footstep k takes Δv_k = A_adj ξ̃ (eq. 32), limited to the reach
        (``clamp_to_reach``).  While its swing is frozen (the last 20 % of single support) it
        keeps the target the foot is already going to.  What footstep k cannot take, the part of
        ξ̃ its Δv_k does not cancel at its own adjustment instant (eq. 31),
        r = ξ̃ − Δv_k / A_adj,k, goes to the footstep after it, by the same eq. (32).  Every term
        is continuous in time, and at k's touchdown the committed footstep makes the new
        ξ_ref carry exactly the Δξ of footstep k (the next one's term is unchanged): ξ_adj and the
        commanded VRP do not jump when a push saturates or outlasts an adjustment.
        """
        plan, preview = self.plan, self.plan.preview
        self.adjusted_target = self.recovery_target = None
        k = plan.next_modifiable_step(t)
        if k is None:
            return np.zeros(3)
        if self.control.recovery in ("multi_step", "multi_step_timing"):
            return self._adjust_multi(t, local, k, xi_error)
        target = self._target(k, xi_error, plan.stance_for(k))
        if self.swing_step == k:
            if self.swing.frozen(t):
                target = np.array([*self.swing.target[:2], plan.steps[k].position[2]])
            else:
                self.swing = self.swing.retarget(t, target)
        self.adjusted_target = (k, target)
        dv = target - plan.steps[k].position
        selection = plan.selection(k)
        delta = dcm_adjustment(preview, local, selection, dv)
        residual = xi_error - dv / self._gain(k)
        residual[2] = 0.0
        k2 = k + 1
        if k2 < len(plan.steps) and float(residual @ residual) > 1e-18:
            stance = plan.steps[k].moved(target)  # footstep k where it will land
            target2 = self._target(k2, residual, stance)
            dv2 = target2 - plan.steps[k2].position
            delta = delta + dcm_adjustment(preview, local, plan.selection(k2), dv2)
            self.recovery_target = (k2, target2)
        return delta

    # -- multi-step recovery and step timing (issue 11; dcmviz.recovery, dcmviz.gait.timing) ---
    def _adjust_multi(self, t: float, local: float, k: int, xi_error: np.ndarray) -> np.ndarray:
        """Δξ_adj with the next MULTI_STEPS footsteps sharing ξ̃ through one QP (dcmviz.recovery),
        their present leverages bounded by what the CoP can still do (``_capacity``)."""
        plan, preview = self.plan, self.plan.preview
        solution, candidates = self._solve_multi(plan, t, local, k, xi_error)
        self._last_slack = float(np.linalg.norm(solution.slack))
        dvs = solution.dv
        delta = np.zeros(3)
        for j, dv in enumerate(dvs, start=k):
            delta = delta + dcm_adjustment(preview, local, plan.selection(j), dv)
        target = plan.steps[k].position + dvs[0]
        if self.swing_step == k and candidates[0].fixed is None:
            self.swing = self.swing.retarget(t, target)
        self.adjusted_target = (k, target)
        if len(dvs) > 1:
            self.recovery_target = (k + 1, plan.steps[k + 1].position + dvs[1])
        return delta

    def _solve_multi(
        self, plan: GaitPlan, t: float, local: float, k: int, xi_error: np.ndarray
    ) -> tuple[recovery.Solution, list[Candidate]]:
        weights = plan.preview.dcm_weights(local)  # a_j(t) = w(t)·s_j (eqs. 22, 33-35)
        gain = self._gain if plan is self.plan else (lambda j: self._gain_of(plan, j))
        candidates = []
        for j in range(k, min(k + MULTI_STEPS, len(plan.steps))):
            fixed = None
            if j == k and self.swing_step == k and self.swing.frozen(t):
                fixed = self.swing.target[:2] - plan.steps[k].position[:2]
            selection = plan.selection(j)
            candidates.append(
                Candidate(
                    plan.steps[j], 1.0 / gain(j), self._instant(j, plan) - t,
                    fixed, self._tread_box(plan.steps[j]), float(weights @ selection),
                )
            )  # fmt: skip
        solution = recovery.solve_full(
            candidates, plan.stance_for(k), xi_error, self.spec,
            self.control.max_step_adjustment, self.b, capacity=self._capacity(plan, t, local),
        )  # fmt: skip
        return solution, candidates

    def _capacity(self, plan: GaitPlan, t: float, local: float) -> recovery.Capacity:
        """What the CoP can still remove of ε = ξ − ξ_adj (dcmviz.recovery): an offset δ from
        v_ref held for CAPACITY_TIME_CONSTANTS · b removes (1 − e^{−τ/b}) δ; v_ref + δ stays
        CAPACITY_MARGIN_M inside the sole of the stance foot (in its axes).  In double support
        the box moves linearly from the old stance foot's sole to the new one's (start: from
        both feet's bounding box; stop: to it), so the capacity, and with it the QP's answer,
        is continuous at every lift-off and touchdown (ξ_adj never jumps)."""
        contact = plan.contact(t)
        kind = contact.kind
        if kind == "ss":
            boxes, s = [self._sole_box([self.placed[OTHER[contact.swing_side]]])], 0.0
        else:
            T = float(plan.preview.durations[contact.phase]) if kind != "stand" else 1.0
            s = min(max(contact.t_phase / T, 0.0), 1.0) if kind != "stand" else 1.0
            both = self._sole_box([self.placed[x] for x in SIDES])
            k = plan.next_modifiable_step(t)
            nxt = self._sole_box([plan.stance_for(k)]) if k is not None else both
            if kind == "ds" and contact.step >= 0:  # after footstep contact.step landed
                old = self._sole_box([plan.stance_for(contact.step)])
                boxes = [old, nxt]
            elif kind == "ds" or kind in ("start_a", "stand"):
                boxes = [both, both] if kind != "ds" else [both, nxt]
            elif kind == "start_b":
                boxes = [both, nxt]
            else:  # stop: from the last stance foot to both feet
                last = self._sole_box([plan.stance_for(len(plan.steps) - 1)])
                boxes = [last, both]
        lo = (1.0 - s) * boxes[0][0] + s * boxes[-1][0]
        hi = (1.0 - s) * boxes[0][1] + s * boxes[-1][1]
        g = 1.0 - math.exp(-CAPACITY_TIME_CONSTANTS)
        # the nominal VRP: with the observer both v_ref and the soles' image in VRP space move
        # by the same −b²F̂/m (eqs. 47-49), so the CoP's room is read without that shift
        v = plan.preview.vrp(local)[:2] if local < plan.duration else plan.preview.waypoints[-1][:2]
        lo = np.minimum(g * (lo - v), 0.0)
        hi = np.maximum(g * (hi - v), 0.0)
        return recovery.Capacity(np.eye(2), lo, hi)

    def _sole_box(self, feet: list[Footstep]) -> tuple[np.ndarray, np.ndarray]:
        """World-axes bounding box (lo, hi) of the soles, CAPACITY_MARGIN_M inside."""
        length = self.spec.foot_length_m - 2 * CAPACITY_MARGIN_M
        width = self.spec.foot_width_m - 2 * CAPACITY_MARGIN_M
        corners = np.vstack([sole_corners(f.position, f.yaw, length, width) for f in feet])
        return corners.min(axis=0), corners.max(axis=0)

    def _retime(self, t: float, xi: np.ndarray, shift: np.ndarray) -> bool:
        """Step timing (``multi_step_timing``, dcmviz.gait.timing): every RETIME_PERIOD_S the
        candidate timings are compared by the recovery QP's CoP shortfall σ (then step size and
        distance from the nominal timing); every tick the walked plan's durations move towards
        the best at most timing.RATE s per s, the swing foot re-timed with them.  True when the
        plan changed."""
        plan = self.plan
        local = t - plan.t0
        if local < 0.0 or local >= plan.duration:
            return False
        k = plan.next_modifiable_step(t)
        if k is None:
            return False
        self._retime_tick += 1
        nominal = self._nominal_durations
        at_nominal = np.array_equal(plan.preview.durations, nominal)
        if at_nominal and self._last_slack < QUIET_SLACK_M:  # capturable as planned: keep it
            self._timing_target = None
            return False
        every = max(1, round(RETIME_PERIOD_S / self.dt))
        if self._retime_tick % every == 1 % every or self._timing_target is None:
            phases = timing.PHASES if self.config.gait.mode == "plan" else 1
            best, best_score, kept_score = None, math.inf, math.inf
            candidates = timing.timing_candidates(plan, local, phases)
            previous = self._timing_target
            if previous is not None and len(previous) == len(plan.preview.durations):
                candidates.append(previous)
            for i, durations in enumerate(candidates):
                p = timing.retimed(plan, durations)
                error = xi - (p.preview.dcm(local) + shift)
                solution, _ = self._solve_multi(p, t, local, k, error)
                short = self._capture_shortfall(p, t, k, xi[:2], solution.dv)
                score = (
                    float(solution.slack @ solution.slack)
                    + CAPTURE_WEIGHT * float(short @ short)
                    + STEP_COST_WEIGHT * solution.step_cost
                    + TIMING_COST_WEIGHT * float(np.sum((durations - nominal) ** 2))
                )
                if previous is not None and i == len(candidates) - 1:
                    kept_score = score
                elif score < best_score - 1e-12:
                    best, best_score = durations, score
            # hysteresis: the target changes only for a clearly better timing (no chattering)
            if best_score < TIMING_HYSTERESIS * kept_score - 1e-9:
                self._timing_target = best
        current = plan.preview.durations
        if self._timing_target is None or len(self._timing_target) != len(current):
            return False
        new = timing.towards(current, self._timing_target, timing.RATE * self.dt)
        phase = int(plan.preview.phase_at(local)[0])
        new[:phase] = current[:phase]  # phases already over stay as walked
        if np.allclose(new, current, rtol=0.0, atol=1e-12):
            return False
        self.plan = timing.retimed(plan, new)
        self.plan_version += 1
        if self.swing is not None and self.swing_step is not None:
            t_touch = self.plan.swing_window(self.swing_step)[1]
            self.swing = self.swing.retime(t, t_touch)
        return True

    def _capture_shortfall(
        self, plan: GaitPlan, t: float, k: int, xi: np.ndarray, dvs: list[np.ndarray]
    ) -> np.ndarray:
        """How far from capturable ``plan``'s timing leaves ξ (timing.capture_shortfall): the
        supports from now until footstep k+1's foot takes the weight (the end of the double
        support after it lands; the stance sole, then both soles, …, with footsteps k, k+1 where
        the QP puts them), the region being footstep k+1's sole: the foot after it cannot cross
        to the side it stands on.  Without a footstep k+1: footstep k's sole at its touchdown."""
        feet = {s: self.placed[s] for s in SIDES}
        landed = [plan.steps[j].moved(plan.steps[j].position + dvs[j - k])
                  for j in range(k, min(k + 2, len(plan.steps)))]  # fmt: skip
        segments = []
        now = t
        for j, step in enumerate(landed, start=k):
            t_lift, t_touch = plan.swing_window(j)
            if now < t_lift:  # double support before the swing: both feet
                segments.append((t_lift - now, *self._sole_box([feet[x] for x in SIDES])))
                now = t_lift
            stance = feet[OTHER[step.side]]
            segments.append((max(t_touch - now, 0.0), *self._sole_box([stance])))
            now = max(now, t_touch)
            feet[step.side] = step
        if len(landed) == 2 and k + 2 < len(plan.steps):
            t_lift = plan.swing_window(k + 2)[0]
            segments.append((max(t_lift - now, 0.0), *self._sole_box([feet[x] for x in SIDES])))
        region = self._sole_box([landed[-1]])
        return timing.capture_shortfall(xi, segments, region, self.b)

    def _inside_support(self, v: np.ndarray, support: dict[str, bool]) -> np.ndarray:
        """The commanded VRP brought into the support polygon (the soles bearing weight, their
        hull in double support) by the projection that keeps its lateral part first (metric
        LATERAL_PRIORITY² on the feet's lateral axis) when it lies laterally beyond both feet:
        no footstep can take a lateral error towards the stance foot, a forward one the next
        footsteps can.  A VRP inside, or laterally between the feet, is kept (the backend's
        support then decides, as for the paper's strategy)."""
        feet = [self.placed[s] for s in SIDES if support.get(s)]
        if not feet:
            return v
        yaw = math.atan2(sum(math.sin(f.yaw) for f in feet), sum(math.cos(f.yaw) for f in feet))
        c, s_ = math.cos(yaw), math.sin(yaw)
        to_local = np.array([[c, s_], [-s_ * LATERAL_PRIORITY, c * LATERAL_PRIORITY]])
        corners = np.vstack(
            [sole_corners(f.position, f.yaw, self.spec.foot_length_m, self.spec.foot_width_m)
             for f in feet]
        )  # fmt: skip
        local_v = to_local @ v[:2]
        lateral = [float(to_local[1] @ self.placed[x].position[:2]) for x in SIDES]
        beyond = max(min(lateral) - local_v[1], local_v[1] - max(lateral), 0.0)
        if beyond == 0.0:  # between the feet: a step can take it
            return v
        polygon = convex_hull(corners @ to_local.T)
        p, d = project_to_polygon(local_v, polygon)
        if d == 0.0:
            return v
        # blended in over PRIORITY_BLEND_M beyond the outer foot: continuous in v
        alpha = min(beyond / (LATERAL_PRIORITY * PRIORITY_BLEND_M), 1.0)  # beyond: scaled
        moved = np.linalg.solve(to_local, np.asarray(p, float)) - v[:2]
        return np.array([*(v[:2] + alpha * moved), v[2]])

    def _instant(self, k: int, plan: GaitPlan | None = None) -> float:
        """Global time of footstep k's adjustment instant (eq. 31): the start of its first
        affected phase, or the end of the plan for the closing step."""
        plan = self.plan if plan is None else plan
        if plan.is_closing_step(k):
            return plan.t_end
        return plan.phase_start(plan.first_affected_phase(k))

    @staticmethod
    def _gain_of(plan: GaitPlan, k: int) -> float:
        """A_adj of footstep k in ``plan`` (see ``_gain``, which caches it for the walked plan)."""
        selection = plan.selection(k)
        if plan.is_closing_step(k):
            return 1.0 / float(plan.preview.W_xi_ref_T[-1] @ selection)
        return adjustment_gain(plan.preview, plan.first_affected_phase(k), selection)

    # -- end of multi-step recovery and step timing --------------------------------------------

    def _gain(self, k: int) -> float:
        """A_adj of footstep k (eq. 32) as a scalar.

        The paper's condition (eq. 31) asks the adjustment to cancel ξ̃ at the start of the first
        phase footstep k moves.  The closing footstep of a plan only moves the final standing
        point, with weight 1/2, and barely moves the DCM at that instant (A_adj of 9–16, 3.5e7
        for order 0 with a long T_stop): a small error would saturate it at the reach limit.
        For it the condition is taken where the plan ends, where ξ_ref_T equals the final VRP
        (terminal constraint, eq. 17): A_adj = 2.
        """
        key = (self.plan_version, k)
        if key not in self._gains:  # one value per footstep and plan: cached for the ticks
            if len(self._gains) > 64:
                self._gains.clear()
            plan = self.plan
            selection = plan.selection(k)
            if plan.is_closing_step(k):
                self._gains[key] = 1.0 / float(plan.preview.W_xi_ref_T[-1] @ selection)
            else:
                phi = plan.first_affected_phase(k)
                self._gains[key] = adjustment_gain(plan.preview, phi, selection)
        return self._gains[key]

    def _target(self, k: int, xi_error: np.ndarray, stance: Footstep) -> np.ndarray:
        """Where footstep k lands for the DCM error ``xi_error``: eq. (32), horizontal, reachable."""
        nominal = self.plan.steps[k]
        dv = self._gain(k) * np.asarray(xi_error, dtype=float)
        dv[2] = 0.0
        target = clamp_to_reach(
            self.spec,
            stance,
            nominal.moved(nominal.position + dv),
            nominal.position,
            self.control.max_step_adjustment,
        )
        return self._on_tread(nominal, target)

    def _tread_box(self, nominal: Footstep) -> tuple[np.ndarray, np.ndarray] | None:
        """Bounds of Δv_xy that keep footstep ``nominal`` on its tread (see ``_on_tread``)."""
        if self.terrain.flat:
            return None
        box = self.terrain.support_under(nominal.position[:2])
        if box is None:
            return None
        p = nominal.position[:2]
        corners = np.array([box.clamp(p + d, self._tread_margin(box)) for d in
                            ((-9.0, -9.0), (9.0, 9.0), (-9.0, 9.0), (9.0, -9.0))])  # fmt: skip
        return corners.min(axis=0) - p, corners.max(axis=0) - p

    def _tread_margin(self, box) -> float:
        margin = EDGE_MARGIN_M + 0.5 * math.hypot(self.spec.foot_length_m, self.spec.foot_width_m)
        if box.size[0] < 2 * margin or box.size[1] < 2 * margin:
            margin = EDGE_MARGIN_M + 0.5 * self.spec.foot_length_m
        return margin

    def _on_tread(self, nominal: Footstep, target: np.ndarray) -> np.ndarray:
        """On terrain an adjusted footstep stays on its nominal tread, the whole sole at least
        EDGE_MARGIN_M inside its edges, so it never straddles an edge and its height (the
        tread's, the z of its VRP waypoints) does not change: ξ_adj stays continuous.  What the
        tread cannot take goes to the next footstep like any other limit (``_adjust``)."""
        if self.terrain.flat:
            return target
        box = self.terrain.support_under(nominal.position[:2])
        if box is None:
            return target
        xy = box.clamp(target[:2], self._tread_margin(box))
        return np.array([xy[0], xy[1], nominal.position[2]])

    def done(self, t: float) -> bool:
        return self.config.gait.mode == "plan" and t >= self.plan.t_end

    # -- events ---------------------------------------------------------------------------------
    def _liftoff(self, state: MeasuredState, k: int) -> None:
        step = self.plan.steps[k]
        lift = Footstep(
            step.side, np.array(state.feet[step.side], float), float(state.feet_yaw[step.side])
        )
        t_lift, t_touch = self.plan.swing_window(k)
        self.swing = SwingTrajectory.between(
            t_lift, t_touch, lift, step, terrain=self.terrain,
            sole=(self.spec.foot_length_m, self.spec.foot_width_m),
        )  # fmt: skip
        self.swing_step = k

    def _touchdown(self, state: MeasuredState) -> None:
        """Commit the footstep where the foot landed (horizontal), then replan if continuous."""
        k = self.swing_step
        plan = self.plan
        step = plan.steps[k]
        nominal = self.nominal_step_position(k)
        landed = np.array([state.feet[step.side][0], state.feet[step.side][1], step.position[2]])
        self.plan = plan.with_step(k, landed)
        self.plan_version += 1
        t_touch = plan.swing_window(k)[1]
        self.placed[step.side] = self.plan.steps[k]
        records = (
            *self.records,
            StepRecord(t_touch, self.steps_completed, step.side, landed, nominal),
        )
        if self.config.gait.mode == "continuous":  # an endless walk: its latest footsteps only
            records = records[-RECORDS_KEPT:]
        self.records = records
        self.steps_completed += 1
        self.swing = None
        self.swing_step = None
        if self.config.gait.mode == "continuous":
            self._nominal_feet[step.side] = Footstep(step.side, nominal, step.yaw)
            steps = horizon_steps(
                self.config.gait,
                self._nominal_feet,
                OTHER[step.side],
                horizon_count(self.config.gait, self.b),
            )
            steps = on_terrain(steps, self.terrain)
            self.plan = build_plan(
                dict(self.placed),
                steps,
                timing_of(self.config.gait),
                self.b,
                self.config.dcm.order,
                start="transfer",
                landed=step.side,
                t0=t_touch,
                spec=self.spec,
                nominal_feet=self._nominal_feet,
            )
            self.nominal_plan = self.plan  # the horizon as generated, before any adjustment
            self._nominal_durations = self.plan.preview.durations.copy()
            self._timing_target = None

    @property
    def next_step_index(self) -> int:
        """Index into ``plan.steps`` of the first footstep not yet landed (continuous mode
        replans at every touchdown, so its plan starts with the next footstep)."""
        return self.steps_completed if self.config.gait.mode == "plan" else 0

    def nominal_step_position(self, k: int) -> np.ndarray:
        """Where footstep k of the current plan was before any adjustment (continuous mode: the
        nominal plan is the horizon as generated at the last replanning)."""
        return np.array(self.nominal_plan.steps[k].position, float)

    @property
    def step_adjustments(self) -> list[dict[str, float]]:
        """Committed footsteps that landed away from the nominal plan: {t, dx, dy} (m)."""
        return [
            {"t": r.t, "step": r.step, "dx": float(r.adjustment[0]), "dy": float(r.adjustment[1])}
            for r in self.records
        ]
