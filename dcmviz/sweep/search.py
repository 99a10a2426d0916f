"""The largest push a walk survives: rollouts of one trial with different push forces, and the
1-D boundary search over the push magnitude (coarse grid, then bisection)."""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from dcmviz.cli import BadInput
from dcmviz.config import Config
from dcmviz.gait import plan_from_config
from dcmviz.session import Session


@dataclass(frozen=True)
class Trial:
    """Everything a worker needs for the rollouts of one envelope cell (picklable)."""

    config: Config  # preset with the controller set and no pushes of its own
    backend: str
    start_s: float  # push start
    duration_s: float  # push duration
    end_s: float  # the run ends here (survived = not fallen by then)
    body: str = "torso"
    ramp_s: float = 0.0


class Rollouts:
    """Rollouts of one trial with different push forces.

    Every rollout is identical until the push starts, so the session is simulated to that instant
    once and deep-copied for each force (falls back to a fresh run if the backend cannot be copied).
    """

    def __init__(self, trial: Trial) -> None:
        self.trial = trial
        self.runs = 0
        session = Session(trial.config, backend=trial.backend)
        session.run(max(0.0, trial.start_s - session.t), stop_on_fall=True)
        try:
            self.snapshot: Session | None = copy.deepcopy(session)
        except Exception:  # noqa: BLE001 - any backend that refuses to be copied
            self.snapshot = None

    def _start(self) -> Session:
        if self.snapshot is not None:
            return copy.deepcopy(self.snapshot)
        session = Session(self.trial.config, backend=self.trial.backend)
        session.run(max(0.0, self.trial.start_s - session.t), stop_on_fall=True)
        return session

    def survives(self, force: Sequence[float]) -> bool:
        """Walk on with one push of ``force`` (N, world); True if not fallen by ``end_s``."""
        trial = self.trial
        session = self._start()
        session.push(
            force, trial.duration_s, ramp=trial.ramp_s, body=trial.body, start=trial.start_s
        )
        session.run(trial.end_s - session.t, stop_on_fall=True)
        self.runs += 1
        return not session.fell


def survives(trial: Trial, force: Sequence[float]) -> bool:
    """One rollout of ``trial`` with a push of ``force`` (N, world): True if it did not fall."""
    return Rollouts(trial).survives(force)


@dataclass
class Boundary:
    """Result of a 1-D search for the largest surviving magnitude."""

    max_ok: float  # largest magnitude known to survive (below the first failure)
    first_fail: float | None  # smallest magnitude known to fall (None: never fell in the bracket)
    non_monotone: list[float] = field(default_factory=list)  # survived above a failure
    runs: int = 0

    @property
    def capped(self) -> bool:
        return self.first_fail is None


def find_boundary(
    ok: Callable[[float], bool], hi: float, *, grid: int = 6, iterations: int = 7
) -> Boundary:
    """Coarse grid over (0, hi], then bisection below the first failing grid point.

    ``ok(0)`` is assumed true.  The result's resolution is hi / grid / 2**iterations.
    """
    points = [hi * (i + 1) / grid for i in range(grid)]
    runs = 0
    lo, fail = 0.0, None
    survived_grid: list[float] = []
    for p in points:
        runs += 1
        if ok(p):
            survived_grid.append(p)
            if fail is None:
                lo = p
        elif fail is None:
            fail = p  # keep scanning: a survivor above it shows non-monotonicity
    if fail is None:
        return Boundary(lo, None, [], runs)
    above = [p for p in survived_grid if p > fail]
    hi_b = fail
    for _ in range(iterations):
        mid = 0.5 * (lo + hi_b)
        runs += 1
        if ok(mid):
            lo = mid
        else:
            hi_b = mid
    return Boundary(lo, hi_b, above, runs)


def push_window(config: Config, step: int, phase: float) -> tuple[float, float, float]:
    """(push start, lift-off, touchdown) in s for a push at ``phase`` of step ``step``'s single
    support (``step`` 1-based, in the nominal plan)."""
    plan = plan_from_config(config)
    if not 1 <= step <= len(plan.steps):
        raise BadInput(f"--step {step}: the preset's plan has steps 1..{len(plan.steps)}")
    t_lift, t_touch = plan.swing_window(step - 1)
    return t_lift + phase * (t_touch - t_lift), t_lift, t_touch
