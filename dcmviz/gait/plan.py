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

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from dcmviz.config import GaitSection
from dcmviz.dcm import Preview, adjustment_gain, continuity_waypoints, vrp_height
from dcmviz.gait.height import step_heights
from dcmviz.robots.feet import OTHER, Footstep
from dcmviz.robots.spec import RobotSpec

START_SPLIT = 0.5  # fraction of t_start spent in start_a (mid0 → w2); the rest in start_b


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
        return vrp_height(self.b)

    @property
    def duration(self) -> float:
        return self.preview.duration

    @cached_property
    def t_end(self) -> float:
        """Global time (s) the plan ends (read every tick: once per plan)."""
        return self.t0 + self.preview.duration

    @property
    def waypoints(self) -> np.ndarray:
        return self.preview.waypoints

    @property
    def durations(self) -> np.ndarray:
        return self.preview.durations

    def selection(self, k: int) -> np.ndarray:
        """S_adj of eq. (29) for footstep k as scalar weights (n_wp,); the 3-D matrix is kron(·, I).

        Read-only, built once per plan and footstep (the walker reads it every tick)."""
        return self._selections[k]

    @cached_property
    def _selections(self) -> tuple[np.ndarray, ...]:
        n_wp = len(self.preview.waypoints)
        rows = []
        for weights in self.step_waypoint_weights:
            s = np.zeros(n_wp)
            for i, w in weights.items():
                s[i] = w
            s.flags.writeable = False
            rows.append(s)
        return tuple(rows)

    @cached_property
    def _next_ss_step(self) -> tuple[int | None, ...]:
        """Per phase: the footstep of the first single-support phase at or after it, or None."""
        out: list[int | None] = [None] * len(self.phase_kind)
        following = None
        for p in range(len(self.phase_kind) - 1, -1, -1):
            if self.phase_kind[p] == "ss":
                following = self.phase_step[p]
            out[p] = following
        return tuple(out)

    def adjustment_gain(self, k: int) -> float:
        """A_adj of footstep k (eq. 32) as a scalar, computed once per plan and footstep.

        The paper's condition (eq. 31) asks the adjustment to cancel ξ̃ at the start of the first
        phase footstep k moves.  The closing footstep of a plan only moves the final standing
        point, with weight 1/2, and barely moves the DCM at that instant (A_adj of 9–16, 3.5e7
        for order 0 with a long T_stop): a small error would saturate it at the reach limit.
        For it the condition is taken where the plan ends, where ξ_ref_T equals the final VRP
        (terminal constraint, eq. 17): A_adj = 2.
        """
        gains = self._gains
        if k not in gains:
            selection = self.selection(k)
            if self.is_closing_step(k):
                gains[k] = 1.0 / float(self.preview.W_xi_ref_T[-1] @ selection)
            else:
                gains[k] = adjustment_gain(self.preview, self.first_affected_phase(k), selection)
        return gains[k]

    @cached_property
    def _gains(self) -> dict[int, float]:
        return {}

    def adjustment_instant(self, k: int) -> float:
        """Global time of footstep k's adjustment instant (eq. 31): the start of its first
        affected phase, or the end of the plan for the closing step."""
        if self.is_closing_step(k):
            return self.t_end
        return self.phase_start(self.first_affected_phase(k))

    def stance_for(self, k: int) -> Footstep:
        """The foot that stands while footstep k swings."""
        side = OTHER[self.steps[k].side]
        for j in range(k - 1, -1, -1):
            if self.steps[j].side == side:
                return self.steps[j]
        return self.start_feet[side]

    def is_closing_step(self, k: int) -> bool:
        """True for the last footstep of a plan, whose only waypoint is the final standing VRP."""
        return k == len(self.steps) - 1 and self.phase_kind[-1] == "stop"

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
        return self._next_ss_step[int(phase)]

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
    start_com: np.ndarray | None = None,
    spec: RobotSpec | None = None,
    nominal_feet: dict[str, Footstep] | None = None,
) -> GaitPlan:
    """Assemble waypoints, durations and phases for ``steps`` and build the preview.

    ``start="stand"``: both feet down, DCM at rest between them (D1, D2 via eq. 26); the plan ends
    standing between the last two feet (D3 + terminal constraint 17).  ``start="transfer"``: t0 is the
    touchdown of foot ``landed`` (already in ``start_feet``); the plan begins with the double support
    that moves the VRP from the other foot onto it.

    ``start_com`` (stand start): the measured CoM of the robot at rest, where the DCM and the
    standing VRP are at t0 (D1).  The VRP then moves from there to Δz_vrp = g b² above the stance
    foot through the start phase, so a b that does not match the robot's present height changes
    it smoothly instead of making the vertical reference jump.  Without it the standing VRP is
    Δz_vrp above the middle of the feet.

    ``spec``: the robot's legs lower the VRP waypoints of a footstep whose stride they cannot
    span at Δz_vrp (:mod:`dcmviz.gait.height`); without it every waypoint is Δz_vrp above its foot.
    The strides are measured from ``nominal_feet`` (default ``start_feet``): a replanning after an
    adjusted footstep keeps the heights the previous plan had, so the reference does not jump.
    """
    if len(steps) == 0:
        raise ValueError("steps: a plan needs at least one footstep")
    dz = np.array([0.0, 0.0, vrp_height(b)])
    height_feet = dict(nominal_feet if nominal_feet is not None else start_feet)
    step_dz = [np.array([0.0, 0.0, h]) for h in step_heights(spec, dz[2], height_feet, steps)]
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
        mid0 = (
            0.5 * (feet["left"].position + feet["right"].position) + dz
            if start_com is None
            else np.asarray(start_com, dtype=float)
        )
        wps += [mid0, mid0, stance.position + step_dz[0]]  # w2 is solved below (D2)
        add_phase("start_a", -1, START_SPLIT * timing.t_start)
        add_phase("start_b", -1, (1.0 - START_SPLIT) * timing.t_start)
    elif start == "transfer":
        if landed is None:
            raise ValueError("landed: a transfer plan needs the side that just touched down")
        stance = feet[landed]
        other = feet[OTHER[landed]]
        (landed_dz,) = step_heights(
            spec, dz[2], {OTHER[landed]: height_feet[OTHER[landed]]}, (height_feet[landed],)
        )
        landed_dz = np.array([0.0, 0.0, landed_dz])
        wps += [other.position + landed_dz, stance.position + landed_dz]
        add_phase("ds", -1, timing.t_ds)
    else:
        raise ValueError(f"start = {start!r}: allowed 'stand' or 'transfer'")

    liftoff: list[Footstep] = []
    n = len(steps)
    last = {
        side: -1 for side in feet
    }  # per side: the footstep its foot stands on (-1: a start foot)
    for k, step in enumerate(steps):
        liftoff.append(feet[step.side])
        stance = feet[OTHER[step.side]]
        # ss_k: VRP stays on the stance foot while step k swings
        wps.append(stance.position + step_dz[k])
        add_phase("ss", k, timing.t_ss)
        feet[step.side] = step
        last[step.side] = k
        if k < n - 1:
            wps.append(step.position + step_dz[k])  # ds_k: onto the new foot
            add_phase("ds", k, timing.t_ds)
            weights[k][len(wps) - 1] = 1.0
        else:
            wps.append(0.5 * (stance.position + step.position) + step_dz[k])  # stop: between feet
            add_phase("stop", k, timing.t_stop)
            weights[k][len(wps) - 1] = 0.5
            # ... and the footstep the stance foot stands on (if it is one) moves it by half too:
            # without it an adjusted penultimate footstep left the final standing DCM where the
            # nominal feet would have been (a G1 stood with it on a sole's corner and fell)
            if last[stance.side] >= 0:
                weights[last[stance.side]][len(wps) - 1] = 0.5
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
