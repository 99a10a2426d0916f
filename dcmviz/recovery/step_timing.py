"""``multi_step_timing``: :mod:`.multi_step` and the phase durations as a recovery variable
(:mod:`dcmviz.gait.timing`)."""

from __future__ import annotations

import math

import numpy as np

from dcmviz.gait import timing
from dcmviz.gait.plan import GaitPlan
from dcmviz.gait.walk import Walk
from dcmviz.recovery.multi_step import MultiStep
from dcmviz.robots.feet import OTHER, SIDES

QUIET_SLACK_M = 1e-4  # m: below this shortfall a nominal timing is not questioned
RETIME_PERIOD_S = 0.03  # s between comparisons of candidate timings
STEP_COST_WEIGHT = 1e-3  # timing score: Σ ω |Δv|² (m²) against σ² (m²) ...
TIMING_COST_WEIGHT = 1e-3  # ... and Σ (T − T_nominal)² (s²)
CAPTURE_WEIGHT = 1.0  # timing score: the capture shortfall² (m²) against σ² (m²)
TIMING_HYSTERESIS = 0.8  # a new target timing must score below this fraction of the kept one
# a push is under way while the observer's shift exceeds the held one by this much (m); the
# capture check assumes it lasts PUSH_PERSISTENCE times as long again as it has lasted so far
PUSH_SHIFT_M = 0.005
PUSH_PERSISTENCE = 1.0


class MultiStepTiming(MultiStep):
    """Every RETIME_PERIOD_S the candidate timings are compared by the recovery QP's CoP
    shortfall σ (then step size and distance from the nominal timing); every tick the walked
    plan's durations move towards the best at most ``timing.RATE`` s per s, the swing foot
    re-timed with them."""

    name = "multi_step_timing"
    uses_held_load = True

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._timing_target: np.ndarray | None = None
        self._retime_tick = 0
        self._nominal_plan: GaitPlan | None = None  # the plan the target was chosen against
        self._push_start: float | None = None  # s, when the push under way began (None: none)

    def retime(
        self,
        walk: Walk,
        t: float,
        xi: np.ndarray,
        shift: np.ndarray,
        max_adjustment: float,
        held: np.ndarray | None = None,
    ) -> GaitPlan | None:
        plan = walk.plan
        persisting = self._push_persistence(t, shift, held)
        if walk.nominal_plan is not self._nominal_plan:  # a new walk or a replanned horizon
            self._nominal_plan = walk.nominal_plan
            self._timing_target = None
        local = t - plan.t0
        if local < 0.0 or local >= plan.duration:
            return None
        k = plan.next_modifiable_step(t)
        if k is None:
            return None
        self._retime_tick += 1
        nominal = walk.nominal_plan.preview.durations  # before any re-timing
        at_nominal = np.array_equal(plan.preview.durations, nominal)
        if at_nominal and self.last_slack < QUIET_SLACK_M:  # capturable as planned: keep it
            self._timing_target = None
            return None
        every = max(1, round(RETIME_PERIOD_S / self.dt))
        if self._retime_tick % every == 1 % every or self._timing_target is None:
            phases = 1 if walk.continuous else timing.PHASES
            best, best_score, kept_score = None, math.inf, math.inf
            candidates = timing.timing_candidates(plan, local, phases)
            previous = self._timing_target
            if previous is not None and len(previous) == len(plan.preview.durations):
                candidates.append(previous)
            # the capture term looks ahead to footstep k+1's support: in VRP space the soles move
            # by the shift of a load that lasts (eqs. 47-49: the contact CoP lies -shift from
            # the VRP), so ξ is compared with them as ξ - held; a push's shift is not (it is
            # over by then: held 0).  With ξ against the soles themselves a pull's lean looked
            # like an uncaught push (Talos fell at 25 %); with the whole shift a push looked
            # caught (the point mass fell at 85 % of its stance-edge bound)
            capture_xi = (xi - (shift if held is None else held))[:2]
            for i, durations in enumerate(candidates):
                p = timing.retimed(plan, durations)
                error = xi - (p.preview.dcm(local) + shift)
                solution, _ = self.solve(walk, p, t, local, k, error, max_adjustment)
                short = self._capture_shortfall(walk, p, t, k, capture_xi, solution.dv, persisting)
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
            return None
        new = timing.towards(current, self._timing_target, timing.RATE * self.dt)
        phase = int(plan.preview.phase_at(local)[0])
        new[:phase] = current[:phase]  # phases already over stay as walked
        if bool((np.abs(new - current) <= 1e-12).all()):  # np.allclose(atol=1e-12), rtol 0
            return None
        return timing.retimed(plan, new)

    def _push_persistence(
        self, t: float, shift: np.ndarray, held: np.ndarray | None
    ) -> tuple[float, np.ndarray] | None:
        """How long the capture check assumes the push under way goes on, and the part of the
        observer's shift that is the push's (shift − held); None without a push.

        The check compares ξ − held with the soles: a push's own shift was left out (it will be
        over before the steps planned now land).  For a short push that is right; for the
        paper's 1 s push pair it is not, and the check found capturable timings that were not
        (Alexander's point mass with the torso lever at 3.62 s, 1.5x: a 0.5 s single support
        and 0.1 s of double support left ξ 0.24 m past the stance sole at the lift-off, where
        the walker's own swings catch 1.74x).  Nobody knows how long a push lasts; that it lasts
        as long again as it has lasted so far is the estimate that grows with the evidence: the
        first ticks of any push count for little, a push that has lasted 0.5 s is taken to
        last 0.5 s more, and one held for T (``sustained_time_s``) becomes the held load."""
        extra = np.asarray(shift, float) - (shift if held is None else held)
        ex, ey = float(extra[0]), float(extra[1])
        if ex * ex + ey * ey <= PUSH_SHIFT_M * PUSH_SHIFT_M:
            self._push_start = None
            return None
        if self._push_start is None:
            self._push_start = t
        lasted = t - self._push_start
        if lasted <= 0.0:
            return None
        return PUSH_PERSISTENCE * lasted, np.array([ex, ey])

    def _capture_shortfall(
        self,
        walk: Walk,
        plan: GaitPlan,
        t: float,
        k: int,
        xi: np.ndarray,
        dvs: list[np.ndarray],
        persisting: tuple[float, np.ndarray] | None = None,
    ) -> np.ndarray:
        """How far from capturable ``plan``'s timing leaves ξ (timing.capture_shortfall): the
        supports from now until footstep k+1's foot takes the weight (the end of the double
        support after it lands; the stance sole, then both soles, …, with footsteps k, k+1 where
        the QP puts them), the region being footstep k+1's sole: the foot after it cannot cross
        to the side it stands on.  Without a footstep k+1: footstep k's sole at its touchdown.
        ``persisting`` (:meth:`_push_persistence`): the push assumed to go on for that long."""
        feet = {s: walk.placed[s] for s in SIDES}
        landed = [plan.steps[j].moved(plan.steps[j].position + dvs[j - k])
                  for j in range(k, min(k + 2, len(plan.steps)))]  # fmt: skip
        segments = []
        now = t
        for j, step in enumerate(landed, start=k):
            t_lift, t_touch = plan.swing_window(j)
            if now < t_lift:  # double support before the swing: both feet
                segments.append((t_lift - now, *self.sole_box([feet[x] for x in SIDES])))
                now = t_lift
            stance = feet[OTHER[step.side]]
            segments.append((max(t_touch - now, 0.0), *self.sole_box([stance])))
            now = max(now, t_touch)
            feet[step.side] = step
        if len(landed) == 2 and k + 2 < len(plan.steps):
            t_lift = plan.swing_window(k + 2)[0]
            segments.append((max(t_lift - now, 0.0), *self.sole_box([feet[x] for x in SIDES])))
        if persisting is not None:  # the push goes on (_push_persistence): its shift moves
            segments = _persist(segments, *persisting)  # the soles' CoP boxes
        region = self.sole_box([landed[-1]])
        return timing.capture_shortfall(xi, segments, region, self.b)


def _persist(
    segments: list[tuple[float, np.ndarray, np.ndarray]], duration: float, shift: np.ndarray
) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """``segments`` (duration, CoP box lo, hi) with the boxes of their first ``duration`` s
    moved by ``shift`` (a force F acting on the DCM is a CoP moved by −b² F/m, the observer's
    shift s: ξ̇ = (ξ − (p + s))/b), a segment split where that time ends."""
    out = []
    left = duration
    for length, lo, hi in segments:
        if left <= 0.0:
            out.append((length, lo, hi))
            continue
        first = min(length, left)
        out.append((first, lo + shift, hi + shift))
        if length > first:
            out.append((length - first, lo, hi))
        left -= first
    return out
