"""Push-recovery strategies: the values of ``control.recovery``, one class each, called by the
walker through one interface (:class:`~dcmviz.recovery.base.RecoveryStrategy`).

* ``next_step`` (:mod:`.next_step`): the paper's step adjustment (§III-A, eqs. 27–35);
* ``multi_step`` (:mod:`.multi_step`): the next three footsteps share the DCM error through one
  small QP (:mod:`.qp`) bounded by what the CoP can still do;
* ``multi_step_timing`` (:mod:`.step_timing`): that, and the phase durations re-timed;
* ``crossover`` (:mod:`.crossover`): that, and the recovery footstep may cross the stance foot.

A new strategy is a new class here and a new value of ``control.recovery``.
"""

from __future__ import annotations

from dcmviz.gait.terrain import Terrain
from dcmviz.recovery.base import NO_ADJUSTMENT, Adjustment, RecoveryStrategy
from dcmviz.recovery.crossover import Crossover
from dcmviz.recovery.multi_step import MultiStep
from dcmviz.recovery.next_step import NextStep
from dcmviz.recovery.qp import Candidate, Capacity, Solution, least_squares, solve, solve_full
from dcmviz.recovery.step_timing import MultiStepTiming
from dcmviz.robots import Robot

STRATEGIES: dict[str, type[RecoveryStrategy]] = {
    cls.name: cls for cls in (NextStep, MultiStep, MultiStepTiming, Crossover)
}


def make_strategy(
    name: str, robot: Robot, terrain: Terrain, b: float, dt: float
) -> RecoveryStrategy:
    """The strategy of ``control.recovery = name`` for one walk; ValueError naming the allowed
    values otherwise."""
    try:
        cls = STRATEGIES[name]
    except KeyError:
        raise ValueError(
            f"control.recovery = {name!r}: allowed {', '.join(map(repr, STRATEGIES))}"
        ) from None
    return cls(robot, terrain, b, dt)


__all__ = [
    "NO_ADJUSTMENT",
    "STRATEGIES",
    "Adjustment",
    "Candidate",
    "Crossover",
    "Capacity",
    "MultiStep",
    "MultiStepTiming",
    "NextStep",
    "RecoveryStrategy",
    "Solution",
    "least_squares",
    "make_strategy",
    "solve",
    "solve_full",
]
