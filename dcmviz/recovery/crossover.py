"""``crossover``: multi_step_timing, and the recovery footstep may cross the stance foot.

No footstep that keeps the swinging leg on its own side can take a push towards the stance foot
beyond the stance-edge bound (:mod:`dcmviz.sweep.bounds`).  Here the next footstep k may also
land across the stance foot, in front of it or behind it, inside the robot's crossover region
(:mod:`dcmviz.robots.crossover`, derived from its legs' kinematics); the paper's adjusted DCM
reference (eqs. 27–35) and the multi-step QP carry the rest, and the footstep after it, which
must stand in reach of footstep k on its own side, uncrosses.

Every tick the QP is solved without crossing and, while footstep k's swing may still be
re-targeted, with footstep k in the front and in the back polygon.  A crossing is taken when it
scores clearly better (the CoP's shortfall σ first, then the footsteps' cost, as the timing score
of :mod:`.step_timing`) and the uncrossed answer leaves the CoP short; it is kept for that
footstep.  The footholds move from the answer of one choice to the other's over ``BLEND_S``, so
ξ_adj = ξ_ref + Σ a_j Δv_j changes continuously (the footholds of both are solved every tick of
the blend).
"""

from __future__ import annotations

import numpy as np

from dcmviz.gait.plan import GaitPlan
from dcmviz.gait.walk import Walk
from dcmviz.recovery import qp
from dcmviz.recovery.base import NO_ADJUSTMENT, Adjustment
from dcmviz.recovery.step_timing import STEP_COST_WEIGHT, MultiStepTiming
from dcmviz.robots.feet import SIDE_SIGN, Footstep

BLEND_S = 0.1  # s over which the footholds move between the uncrossed and the crossed answer
CROSS_RATIO = 0.5  # a crossing is taken when it scores below this fraction of the uncrossed
MIN_SHORTFALL_M = 0.005  # ... and the uncrossed answer leaves the CoP at least this far short
MODES = ("front", "back")
TOWARDS_STANCE_DEG = 60.0  # a crossing is considered for DCM errors this close to across
_COS_TOWARDS = float(np.cos(np.radians(TOWARDS_STANCE_DEG)))


class Crossover(MultiStepTiming):
    """multi_step_timing with crossed footsteps (module docstring)."""

    name = "crossover"
    crosses_legs = True

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.mode = "none"  # "none" | "front" | "back": footstep k crosses in front, behind
        self._mode_step: int | None = None  # the footstep ``mode`` is for
        self._from = "none"  # the choice the footholds blend away from
        self._blend = 1.0  # 0 → 1 over BLEND_S after a change of ``mode``
        # 0 → 1 over BLEND_S after a crossed footstep landed: the commanded VRP, left as it was
        # while that footstep crossed, is brought into the new support's lateral-first shape
        self._landed_blend = 1.0
        self._plan_id: int | None = None  # the walked plan's nominal the step index refers to

    def _region(self, mode: str) -> tuple[np.ndarray, np.ndarray] | None:
        if mode == "none":
            return None
        return self.robot.crossover.halfplanes(mode)

    def _available(self) -> tuple[str, ...]:
        region = self.robot.crossover
        return tuple(m for m in MODES if len(getattr(region, m)) >= 3)

    def solve(self, walk, plan, t, local, k, xi_error, max_adjustment, region=None):
        """The QP with footstep k crossed as the chosen ``mode`` (for the timing comparisons of
        :meth:`retime` too), unless a ``region`` is given."""
        if region is None and k == self._mode_step:
            region = self._region(self.mode)
        return super().solve(walk, plan, t, local, k, xi_error, max_adjustment, region)

    def adjust(
        self, walk: Walk, t: float, local: float, xi_error: np.ndarray, max_adjustment: float
    ) -> Adjustment:
        plan = walk.plan
        k = plan.next_modifiable_step(t)
        if k is None:
            return NO_ADJUSTMENT
        if id(walk.nominal_plan) != self._plan_id or k != self._mode_step:
            # a new footstep (or a replanned horizon): it starts uncrossed
            if self.mode != "none" and id(walk.nominal_plan) == self._plan_id:
                self._landed_blend = 0.0  # the crossed footstep landed (no VRP jump there)
            self._plan_id, self._mode_step = id(walk.nominal_plan), k
            self.mode, self._from, self._blend = "none", "none", 1.0
        elif self._landed_blend < 1.0:
            self._landed_blend = min(1.0, self._landed_blend + self.dt / BLEND_S)
        frozen = walk.swing_step == k and walk.swing.frozen(t)
        crossed_now = self._crossed(walk, plan, k)
        swing = walk.swing
        self._swinging = (
            None if swing is None else (plan.steps[walk.swing_step].side, swing.sample(t)[0])
        )
        answers: dict[str, tuple[qp.Solution, list[qp.Candidate]]] = {}

        def answer(mode: str) -> tuple[qp.Solution, list[qp.Candidate]]:
            if mode not in answers:
                answers[mode] = super(Crossover, self).solve(
                    walk, plan, t, local, k, xi_error, max_adjustment, self._region(mode)
                )
            return answers[mode]

        if (
            not frozen
            and not crossed_now
            and self.mode == "none"
            and self._available()
            and self._towards_stance(plan, k, xi_error)
        ):
            uncrossed = answer("none")[0]
            short = float(np.linalg.norm(uncrossed.slack))
            if short > MIN_SHORTFALL_M:
                best, best_score = None, _score(uncrossed) * CROSS_RATIO
                for mode in self._available():
                    crossed = answer(mode)[0]
                    if float(np.linalg.norm(crossed.slack)) < 1.0 and _score(crossed) < best_score:
                        best, best_score = mode, _score(crossed)
                if best is not None:
                    self._from, self.mode, self._blend = self.mode, best, 0.0
        solution, candidates = answer(self.mode)
        self.last_slack = float(np.linalg.norm(solution.slack))
        dvs = solution.dv
        if self._blend < 1.0:
            self._blend = min(1.0, self._blend + self.dt / BLEND_S)
            before = answer(self._from)[0].dv
            dvs = [
                (1.0 - self._blend) * a + self._blend * b for a, b in zip(before, dvs, strict=True)
            ]
        return self.adjustment(walk, plan, k, candidates, dvs)

    def shape_vrp(
        self,
        v: np.ndarray,
        support: dict[str, bool],
        placed: dict[str, Footstep],
        shift: np.ndarray | None = None,
    ) -> np.ndarray:
        """As multi_step's while uncrossed; while footstep k crosses, a footstep takes the
        lateral error, so the commanded VRP is left to the support as the paper's strategy
        leaves it.  Between the two, blended with the footholds' weight (no jump)."""
        if self.mode == "none" and self._from == "none":
            shaped = super().shape_vrp(v, support, placed, shift)
            if self._landed_blend >= 1.0:
                return shaped
            w = _smoothstep(self._landed_blend)
            return (1.0 - w) * v + w * shaped
        w = self._weight()
        crossed = v if self.mode != "none" else super().shape_vrp(v, support, placed, shift)
        uncrossed = super().shape_vrp(v, support, placed, shift) if self._from == "none" else v
        return (1.0 - w) * uncrossed + w * crossed

    def _weight(self) -> float:
        """The blend's weight of the present choice: a smoothstep of the time since it changed."""
        return _smoothstep(self._blend)

    def _towards_stance(self, plan: GaitPlan, k: int, xi_error: np.ndarray) -> bool:
        """True when the DCM error points across, towards footstep k's stance foot (within
        TOWARDS_STANCE_DEG of its lateral axis): what only a crossing step catches.  An error
        that points elsewhere is the uncrossed strategy's: crossing for it (for the crossover
        region's longer reach forward, say) left Talos standing crossed against the way it
        fell (a 1 s push pair at 1.5x the paper's, bench/robustness.py)."""
        step = plan.steps[k]
        stance = plan.stance_for(k)
        c, s = np.cos(stance.yaw), np.sin(stance.yaw)
        ex, ey = float(xi_error[0]), float(xi_error[1])
        across = -SIDE_SIGN[step.side] * (-s * ex + c * ey)  # towards the stance foot's side
        return across > _COS_TOWARDS * np.hypot(ex, ey)

    def _crossed(self, walk: Walk, plan: GaitPlan, k: int) -> bool:
        """True while the legs stand crossed: footstep k's foot stands across its stance foot
        (it then uncrosses; a crossing never follows a crossing)."""
        step = plan.steps[k]
        stance = plan.stance_for(k)
        foot = walk.placed[step.side].position[:2] - stance.position[:2]
        c, s = np.cos(stance.yaw), np.sin(stance.yaw)
        lateral = SIDE_SIGN[step.side] * (-s * foot[0] + c * foot[1])
        return bool(lateral < self.spec.min_step_width_m - 1e-6)


def _smoothstep(u: float) -> float:
    """0 → 1 with zero rate and acceleration at both ends (u in [0, 1])."""
    return u * u * u * (10.0 - 15.0 * u + 6.0 * u * u)


def _score(solution: qp.Solution) -> float:
    return float(solution.slack @ solution.slack) + STEP_COST_WEIGHT * solution.step_cost
