"""Footstep plans → VRP waypoints, phase durations, contact schedule and swing-foot paths.

Phase structure of a plan (the paper's Fig. 1, stand → walk → stand)::

    start_a  start_b  ss_1  ds_1  ss_2  ds_2 ...  ss_n  stop
    mid0→w2  w2→s0    s0→s0 s0→s1 s1→s1 s1→s2     s_{n-1}→s_{n-1}  s_{n-1}→mid_end

``s_k`` is the VRP above footstep k (sole position + Δz_vrp e_z), ``s0`` the stance foot of the first
step, ``mid0``/``mid_end`` the standing VRPs between the feet (design choices D1, D3) and ``w2`` the
waypoint that makes the DCM start at rest (D2, eq. 26).  During ``ss_k`` the foot of step k swings;
it touches down at the start of ``ds_k``.  A plan may also start at a touchdown (``transfer``), which
the continuous (receding-horizon) mode uses to replan one step at a time.

A :class:`GaitPlan` is immutable; :meth:`GaitPlan.with_step` returns the plan with one footstep moved
(step adjustment, §III-A), which changes only the waypoints of that footstep.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from dcmviz import GRAVITY
from dcmviz.dcm import Preview, continuity_waypoints
from dcmviz.sim.specs import RobotSpec, get_spec

if TYPE_CHECKING:
    from dcmviz.config import Config, GaitSection

OTHER = {"left": "right", "right": "left"}
SIDE_SIGN = {"left": 1.0, "right": -1.0}
START_SPLIT = 0.5  # fraction of t_start spent in start_a (mid0 → w2); the rest in start_b
SWING_HEIGHT_M = 0.06  # apex of the swing above the higher of lift-off and touchdown
RETARGET_FREEZE = 0.8  # the swing target is frozen for the last 20 % of single support


@dataclass(frozen=True)
class Footstep:
    """A sole placement: position of the sole frame origin (m) and yaw (rad)."""

    side: str
    position: np.ndarray
    yaw: float = 0.0

    def moved(self, position: np.ndarray) -> Footstep:
        return Footstep(self.side, np.asarray(position, dtype=float), self.yaw)


@dataclass(frozen=True)
class Timing:
    t_ss: float
    t_ds: float
    t_start: float
    t_stop: float


@dataclass(frozen=True)
class ContactState:
    """The schedule at one time: which feet bear weight, which swings (and where to)."""

    phase: int  # 0-based phase index
    t_phase: float  # s into the phase
    kind: str  # start_a | start_b | ss | ds | stop | stand
    support: dict[str, bool]
    swing_side: str | None
    step: int  # index into plan.steps of the step swinging (ss) / just landed (ds); -1 otherwise
    swing_progress: float  # 0..1 through single support, 0 outside


# ---------------------------------------------------------------------------------------------
# footstep generation


def _heading_offset(yaw: float, side: str, width: float) -> np.ndarray:
    s = SIDE_SIGN[side] * 0.5 * width
    return np.array([-math.sin(yaw) * s, math.cos(yaw) * s, 0.0])


def initial_feet(gait: GaitSection) -> dict[str, Footstep]:
    """Standing feet at t = 0: sole centres at (0, ±step_width/2, 0)."""
    return {
        side: Footstep(side, _heading_offset(0.0, side, gait.step_width), 0.0)
        for side in ("left", "right")
    }


def generated_step(gait: GaitSection, k: int, *, closing: bool) -> Footstep:
    """Footstep k ≥ 1 of the generated plan (midline advances step_length along heading k·turn).

    With ``closing`` the step lands beside the previous one (the plan's last step).
    """
    side = gait.first_swing if k % 2 == 1 else OTHER[gait.first_swing]
    m = np.zeros(3)
    yaw = 0.0
    last = k - 1 if closing else k
    for j in range(1, last + 1):
        yaw = j * gait.turn
        m = m + np.array(
            [gait.step_length * math.cos(yaw), gait.step_length * math.sin(yaw), gait.step_height]
        )
    return Footstep(side, m + _heading_offset(yaw, side, gait.step_width), yaw)


def plan_footsteps(gait: GaitSection) -> tuple[dict[str, Footstep], tuple[Footstep, ...]]:
    """Initial feet and the footsteps of a plan-mode walk (explicit ones if given)."""
    feet = initial_feet(gait)
    if gait.footsteps is not None:
        steps = tuple(
            Footstep(f.side, np.array(f.position, dtype=float), f.yaw) for f in gait.footsteps
        )
    else:
        n = gait.n_steps
        steps = tuple(generated_step(gait, k, closing=(k == n and n > 1)) for k in range(1, n + 1))
    return feet, steps


def check_reachable(config: Config) -> None:
    """ValueError naming the first footstep out of the robot's reach (relative to the stance foot)."""
    spec = get_spec(config.robot.model)
    gait = config.gait
    feet, steps = plan_footsteps(gait)
    if gait.footsteps is None:
        L, w, h = abs(gait.step_length), gait.step_width, abs(gait.step_height)
        for key, value, limit, what in (
            ("step_length", L, spec.max_step_length_m, "≤"),
            ("step_width", w, spec.max_step_width_m, "≤"),
            ("step_height", h, spec.max_step_height_m, "≤"),
        ):
            if value > limit + 1e-12:
                raise ValueError(
                    f"gait.{key} = {getattr(gait, key)}: out of {spec.name}'s reach; "
                    f"allowed |{key}| {what} {limit} m"
                )
        if w < spec.min_step_width_m:
            raise ValueError(
                f"gait.step_width = {w}: the feet of {spec.name} collide; allowed "
                f"≥ {spec.min_step_width_m} m"
            )
        return
    current = dict(feet)
    for i, step in enumerate(steps):
        stance = current[OTHER[step.side]]
        problem = reach_problem(spec, stance, step)
        if problem:
            raise ValueError(f"gait.footsteps[{i}] = {tuple(step.position.tolist())}: {problem}")
        current[step.side] = step


def reach_problem(spec: RobotSpec, stance: Footstep, step: Footstep) -> str:
    """'' if ``step`` is reachable from ``stance``, else why not (stance-foot frame)."""
    d = step.position - stance.position
    c, s = math.cos(stance.yaw), math.sin(stance.yaw)
    dx, dy = c * d[0] + s * d[1], -s * d[0] + c * d[1]
    lateral = SIDE_SIGN[step.side] * dy  # > 0 on the correct side
    if abs(dx) > spec.max_step_length_m + 1e-9:
        return (
            f"out of {spec.name}'s reach from the {stance.side} foot: |Δx| = {abs(dx):.3f} m, "
            f"allowed ≤ {spec.max_step_length_m} m"
        )
    if lateral > spec.max_step_width_m + 1e-9:
        return (
            f"out of {spec.name}'s reach from the {stance.side} foot: width {lateral:.3f} m, "
            f"allowed ≤ {spec.max_step_width_m} m"
        )
    if lateral < spec.min_step_width_m - 1e-9:
        return (
            f"too close to (or across) the {stance.side} foot: width {lateral:.3f} m, "
            f"allowed ≥ {spec.min_step_width_m} m"
        )
    if abs(d[2]) > spec.max_step_height_m + 1e-9:
        return (
            f"height change {d[2]:.3f} m out of {spec.name}'s reach, allowed "
            f"|Δz| ≤ {spec.max_step_height_m} m"
        )
    return ""


def clamp_to_reach(
    spec: RobotSpec, stance: Footstep, step: Footstep, nominal: np.ndarray, max_adjustment: float
) -> np.ndarray:
    """Project an adjusted footstep position onto what is allowed (horizontal only).

    The adjustment relative to ``nominal`` is limited to ``max_adjustment`` (m), then the result is
    clipped to the reach box of the stance foot (no leg crossing, eq. 32 is kept where possible).
    """
    p = np.array(step.position, dtype=float)
    delta = p[:2] - nominal[:2]
    n = float(np.hypot(*delta))
    if n > max_adjustment:
        delta *= max_adjustment / n if n > 0 else 0.0
    p[:2] = nominal[:2] + delta
    c, s = math.cos(stance.yaw), math.sin(stance.yaw)
    d = p[:2] - stance.position[:2]
    dx, dy = c * d[0] + s * d[1], -s * d[0] + c * d[1]
    sign = SIDE_SIGN[step.side]
    dx = min(max(dx, -spec.max_step_length_m), spec.max_step_length_m)
    lateral = min(max(sign * dy, spec.min_step_width_m), spec.max_step_width_m)
    dy = sign * lateral
    p[0] = stance.position[0] + c * dx - s * dy
    p[1] = stance.position[1] + s * dx + c * dy
    p[2] = nominal[2]
    return p


# ---------------------------------------------------------------------------------------------
# the plan


@dataclass(frozen=True)
class GaitPlan:
    """Footsteps, VRP waypoints (one per phase boundary) and their closed-form preview."""

    t0: float  # global time of the plan's local t = 0
    start_feet: dict[str, Footstep]  # feet at t0
    steps: tuple[Footstep, ...]  # footsteps to take, in order
    timing: Timing
    b: float
    order: int
    start: str  # "stand" (D1–D3, Fig. 1) or "transfer" (begins at a touchdown)
    preview: Preview
    phase_kind: tuple[str, ...]
    phase_step: tuple[int, ...]  # per phase: index into steps (ss: swinging, ds: landed), else -1
    # per step: {waypoint index: weight} — the rows of S_adj (eq. 29) for that footstep
    step_waypoint_weights: tuple[dict[int, float], ...]
    liftoff: tuple[Footstep, ...] = field(repr=False)  # per step: where its foot lifts off

    # -- derived ----------------------------------------------------------------------------
    @property
    def dz_vrp(self) -> float:
        """Δz_vrp = g b² (eq. 1)."""
        return GRAVITY * self.b * self.b

    @property
    def duration(self) -> float:
        return self.preview.duration

    @property
    def t_end(self) -> float:
        return self.t0 + self.preview.duration

    @property
    def waypoints(self) -> np.ndarray:
        return self.preview.waypoints

    @property
    def durations(self) -> np.ndarray:
        return self.preview.durations

    def selection(self, k: int) -> np.ndarray:
        """S_adj of eq. (29) for footstep k as scalar weights (n_wp,); the 3-D matrix is kron(·, I)."""
        s = np.zeros(len(self.preview.waypoints))
        for i, w in self.step_waypoint_weights[k].items():
            s[i] = w
        return s

    def stance_for(self, k: int) -> Footstep:
        """The foot that stands while footstep k swings."""
        side = OTHER[self.steps[k].side]
        for j in range(k - 1, -1, -1):
            if self.steps[j].side == side:
                return self.steps[j]
        return self.start_feet[side]

    def first_affected_phase(self, k: int) -> int:
        """φ_fa: the first phase whose VRP interpolation moves with footstep k (= i_fa,wp − 1)."""
        return min(self.step_waypoint_weights[k]) - 1

    def phase_start(self, phase: int) -> float:
        """Global start time of a phase."""
        return self.t0 + float(self.preview.phase_start_times[phase])

    # -- schedule -----------------------------------------------------------------------------
    def contact(self, t: float) -> ContactState:
        """Contact schedule at global time t (after the plan: standing on both feet)."""
        local = t - self.t0
        if local >= self.preview.duration or local < 0.0:
            return ContactState(
                len(self.phase_kind) - 1,
                local,
                "stand",
                {"left": True, "right": True},
                None,
                -1,
                0.0,
            )
        phase, t_phase = self.preview.phase_at(local)
        phase = int(phase)
        kind = self.phase_kind[phase]
        k = self.phase_step[phase]
        if kind == "ss":
            side = self.steps[k].side
            T = float(self.preview.durations[phase])
            return ContactState(
                phase,
                float(t_phase),
                kind,
                {side: False, OTHER[side]: True},
                side,
                k,
                min(1.0, float(t_phase) / T),
            )
        return ContactState(
            phase, float(t_phase), kind, {"left": True, "right": True}, None, k, 0.0
        )

    def next_modifiable_step(self, t: float) -> int | None:
        """The next footstep whose foot is not yet down at global time t (§III-A), or None.

        While a foot swings, that footstep; otherwise the next one to lift off.  The closing step of
        a plan (whose only waypoint is the standing mid-point) counts too.
        """
        local = t - self.t0
        if local < 0.0 or local >= self.preview.duration:
            return None
        phase, _ = self.preview.phase_at(local)
        for p in range(int(phase), len(self.phase_kind)):
            if self.phase_kind[p] == "ss":
                return self.phase_step[p]
        return None

    def swing_window(self, k: int) -> tuple[float, float]:
        """Global lift-off and touchdown times of step k."""
        p = self.phase_step.index(k)  # the ss phase comes first for each step
        t_lift = self.phase_start(p)
        return t_lift, t_lift + float(self.preview.durations[p])

    # -- editing ------------------------------------------------------------------------------
    def with_step(self, k: int, position: np.ndarray) -> GaitPlan:
        """The same plan with footstep k moved to ``position`` (only its waypoints change)."""
        old = self.steps[k]
        delta = np.asarray(position, dtype=float) - old.position
        wp = self.preview.waypoints + np.outer(self.selection(k), delta)
        steps = self.steps[:k] + (old.moved(old.position + delta),) + self.steps[k + 1 :]
        liftoff = list(self.liftoff)
        j = _next_same_side(steps, k)
        if j >= 0:
            liftoff[j] = steps[k]
        return GaitPlan(
            self.t0,
            self.start_feet,
            steps,
            self.timing,
            self.b,
            self.order,
            self.start,
            self.preview.with_waypoints(wp),
            self.phase_kind,
            self.phase_step,
            self.step_waypoint_weights,
            tuple(liftoff),
        )


def _next_same_side(steps: tuple[Footstep, ...], k: int) -> int:
    for j in range(k + 1, len(steps)):
        if steps[j].side == steps[k].side:
            return j
    return -1


def build_plan(
    start_feet: dict[str, Footstep],
    steps: tuple[Footstep, ...],
    timing: Timing,
    b: float,
    order: int,
    *,
    start: str = "stand",
    landed: str | None = None,
    t0: float = 0.0,
) -> GaitPlan:
    """Assemble waypoints, durations and phases for ``steps`` and build the preview.

    ``start="stand"``: both feet down, DCM at rest between them (D1, D2 via eq. 26); the plan ends
    standing between the last two feet (D3 + terminal constraint 17).  ``start="transfer"``: t0 is the
    touchdown of foot ``landed`` (already in ``start_feet``); the plan begins with the double support
    that moves the VRP from the other foot onto it.
    """
    if len(steps) == 0:
        raise ValueError("steps: a plan needs at least one footstep")
    dz = np.array([0.0, 0.0, GRAVITY * b * b])
    feet = dict(start_feet)
    wps: list[np.ndarray] = []
    kinds: list[str] = []
    phase_step: list[int] = []
    durs: list[float] = []
    weights: list[dict[int, float]] = [dict() for _ in steps]

    def add_phase(kind: str, k: int, T: float) -> None:
        kinds.append(kind)
        phase_step.append(k)
        durs.append(T)

    if start == "stand":
        stance = feet[OTHER[steps[0].side]]
        mid0 = 0.5 * (feet["left"].position + feet["right"].position) + dz
        wps += [mid0, mid0, stance.position + dz]  # w2 is solved below (D2)
        add_phase("start_a", -1, START_SPLIT * timing.t_start)
        add_phase("start_b", -1, (1.0 - START_SPLIT) * timing.t_start)
    elif start == "transfer":
        if landed is None:
            raise ValueError("landed: a transfer plan needs the side that just touched down")
        stance = feet[landed]
        wps += [feet[OTHER[landed]].position + dz, stance.position + dz]
        add_phase("ds", -1, timing.t_ds)
    else:
        raise ValueError(f"start = {start!r}: allowed 'stand' or 'transfer'")

    liftoff: list[Footstep] = []
    n = len(steps)
    for k, step in enumerate(steps):
        liftoff.append(feet[step.side])
        stance = feet[OTHER[step.side]]
        # ss_k: VRP stays on the stance foot while step k swings
        wps.append(stance.position + dz)
        add_phase("ss", k, timing.t_ss)
        feet[step.side] = step
        if k < n - 1:
            wps.append(step.position + dz)  # ds_k: onto the new foot
            add_phase("ds", k, timing.t_ds)
            weights[k][len(wps) - 1] = 1.0
        else:
            wps.append(0.5 * (stance.position + step.position) + dz)  # stop: between the feet
            add_phase("stop", k, timing.t_stop)
            weights[k][len(wps) - 1] = 0.5
        # the stance waypoint of the next ss belongs to this footstep as well
        if k + 1 < n:
            weights[k][len(wps)] = 1.0

    wp = np.array(wps)
    durations = np.array(durs)
    if start == "stand":
        wp = continuity_waypoints(wp[0], wp[2:-1], wp[-1], durations, b, order)
    preview = Preview(wp, durations, b, order)
    return GaitPlan(
        t0,
        dict(start_feet),
        tuple(steps),
        timing,
        b,
        order,
        start,
        preview,
        tuple(kinds),
        tuple(phase_step),
        tuple(weights),
        tuple(liftoff),
    )


def timing_of(gait: GaitSection) -> Timing:
    return Timing(gait.t_ss, gait.t_ds, gait.t_start, gait.t_stop)


def plan_from_config(config: Config) -> GaitPlan:
    """The plan-mode walk of a preset: stand → footsteps → stand."""
    feet, steps = plan_footsteps(config.gait)
    return build_plan(feet, steps, timing_of(config.gait), config.dcm.b, config.dcm.order)


def horizon_steps(
    gait: GaitSection, start_feet: dict[str, Footstep], next_side: str, count: int
) -> tuple[Footstep, ...]:
    """``count`` generated footsteps continuing from ``start_feet`` (continuous mode).

    Each step is placed relative to the midline of the two current feet, heading + turn, so an
    adjusted (really landed) foot shifts the walk only through the stance it leaves behind.
    """
    feet = dict(start_feet)
    side = next_side
    out = []
    for _ in range(count):
        stance = feet[OTHER[side]]
        yaw = stance.yaw + gait.turn
        mid = stance.position - _heading_offset(stance.yaw, stance.side, gait.step_width)
        mid = mid + np.array(
            [gait.step_length * math.cos(yaw), gait.step_length * math.sin(yaw), gait.step_height]
        )
        step = Footstep(side, mid + _heading_offset(yaw, side, gait.step_width), yaw)
        out.append(step)
        feet[side] = step
        side = OTHER[side]
    return tuple(out)


# ---------------------------------------------------------------------------------------------
# swing-foot paths


def _quintic_coefficients(
    p0: np.ndarray, v0: np.ndarray, a0: np.ndarray, p1: np.ndarray, T: float
) -> np.ndarray:
    """Coefficients c (6, d) of p(τ) = Σ c_i τ^i with p, ṗ, p̈ given at 0 and p(T) = p1, ṗ = p̈ = 0."""
    c0, c1, c2 = p0, v0, 0.5 * a0
    T2, T3, T4, T5 = T * T, T**3, T**4, T**5
    d = p1 - (c0 + c1 * T + c2 * T2)
    e = -(c1 + 2 * c2 * T)
    f = -(2 * c2)
    c3 = (10 * d - 4 * e * T + 0.5 * f * T2) / T3
    c4 = (-15 * d + 7 * e * T - f * T2) / T4
    c5 = (6 * d - 3 * e * T + 0.5 * f * T2) / T5
    return np.array([c0, c1, c2, c3, c4, c5])


@dataclass(frozen=True)
class SwingTrajectory:
    """A swing foot path from lift-off to touchdown: C² in time, re-targetable mid-swing.

    Horizontal position and yaw follow a quintic to the target with zero end velocity and
    acceleration; the height follows z0 + (z1 − z0) q(s) + h 64 s³ (1 − s)³ (zero velocity and
    acceleration at both ends, apex h above the straight line at mid-swing).
    """

    t_lift: float
    t_touch: float
    start: np.ndarray  # (3,) lift-off position
    target: np.ndarray  # (3,) touchdown position
    yaw_start: float
    yaw_target: float
    height: float
    t_seg: float = 0.0  # start time of the current horizontal segment
    coeffs: np.ndarray | None = None  # (6, 3): x, y, yaw quintic from t_seg to t_touch

    @staticmethod
    def between(
        t_lift: float,
        t_touch: float,
        lift: Footstep,
        touch: Footstep,
        clearance: float = SWING_HEIGHT_M,
    ) -> SwingTrajectory:
        z0, z1 = float(lift.position[2]), float(touch.position[2])
        height = clearance + 0.5 * abs(z1 - z0)
        yaw1 = lift.yaw + math.remainder(touch.yaw - lift.yaw, 2 * math.pi)
        p0 = np.array([lift.position[0], lift.position[1], lift.yaw])
        p1 = np.array([touch.position[0], touch.position[1], yaw1])
        c = _quintic_coefficients(p0, np.zeros(3), np.zeros(3), p1, t_touch - t_lift)
        return SwingTrajectory(
            t_lift,
            t_touch,
            np.array(lift.position, float),
            np.array(touch.position, float),
            lift.yaw,
            yaw1,
            height,
            t_lift,
            c,
        )

    def retarget(self, t: float, target: np.ndarray) -> SwingTrajectory:
        """A path that agrees with this one in position, velocity, acceleration at t, ending at target.

        In the last 20 % of the swing the target is frozen (large accelerations otherwise).
        """
        if t >= self.t_lift + RETARGET_FREEZE * (self.t_touch - self.t_lift) or t >= self.t_touch:
            return self
        target = np.asarray(target, dtype=float)
        if abs(target[0] - self.target[0]) < 1e-6 and abs(target[1] - self.target[1]) < 1e-6:
            return self
        t = max(t, self.t_seg)
        p, v, a = self._horizontal(t)
        p1 = np.array([target[0], target[1], self.yaw_target])
        c = _quintic_coefficients(p, v, a, p1, self.t_touch - t)
        new_target = np.array([target[0], target[1], self.target[2]])
        return SwingTrajectory(
            self.t_lift,
            self.t_touch,
            self.start,
            new_target,
            self.yaw_start,
            self.yaw_target,
            self.height,
            t,
            c,
        )

    def _horizontal(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        tau = min(max(t, self.t_seg), self.t_touch) - self.t_seg
        c0, c1, c2, c3, c4, c5 = self.coeffs  # Horner on (3,) rows
        p = c0 + tau * (c1 + tau * (c2 + tau * (c3 + tau * (c4 + tau * c5))))
        v = c1 + tau * (2 * c2 + tau * (3 * c3 + tau * (4 * c4 + tau * 5 * c5)))
        a = 2 * c2 + tau * (6 * c3 + tau * (12 * c4 + tau * 20 * c5))
        if t >= self.t_touch:
            v, a = np.zeros(3), np.zeros(3)
        return p, v, a

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
        """Position, velocity, acceleration (3,), yaw and yaw rate at global time t."""
        T = self.t_touch - self.t_lift
        s = min(max((t - self.t_lift) / T, 0.0), 1.0)
        p, v, a = self._horizontal(t)
        z0, z1 = self.start[2], self.target[2]
        q = s**3 * (10 - 15 * s + 6 * s * s)
        dq = 30 * s * s * (1 - s) ** 2
        ddq = 60 * s * (1 - s) * (1 - 2 * s)
        bump = 64 * s**3 * (1 - s) ** 3
        dbump = 192 * s * s * (1 - s) ** 2 * (1 - 2 * s)
        ddbump = 192 * s * (1 - s) * (2 - 10 * s + 10 * s * s) if 0 < s < 1 else 0.0
        z = z0 + (z1 - z0) * q + self.height * bump
        dz = ((z1 - z0) * dq + self.height * dbump) / T
        ddz = ((z1 - z0) * ddq + self.height * ddbump) / (T * T)
        if s <= 0.0 or s >= 1.0:
            dz = ddz = 0.0
        pos = np.array([p[0], p[1], z])
        vel = np.array([v[0], v[1], dz])
        acc = np.array([a[0], a[1], ddz])
        return pos, vel, acc, float(p[2]), float(v[2])
