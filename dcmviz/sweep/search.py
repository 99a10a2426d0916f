"""The largest push a walk survives: rollouts of one trial with different push forces, and the
1-D boundary search over the push magnitude (coarse grid, then bisection).

A rollout is a pure function of (trial, force): :func:`prefix_snapshot` simulates a trial up to
the push once and pickles the session's state there (:meth:`Session.save_state`);
:func:`rollout` continues from such a snapshot in a session built for it
(:meth:`Session.from_state`, bit for bit what the walk to the push would give) and walks on
with one push.  The serial path and the Ray tasks run exactly this code, so they give identical
numbers.  :class:`BoundarySearch` is the search as a state machine
(ask for probes, tell their outcomes), so many searches can be driven concurrently.
"""

from __future__ import annotations

import pickle
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

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


@dataclass(frozen=True)
class RolloutResult:
    """What one rollout measured."""

    survived: bool  # not fallen by the trial's end_s
    fall_time_s: float | None  # None if it did not fall
    max_dcm_error_m: float  # largest |ξ − ξ_ref| before a fall, over the whole run
    wall_time_s: float  # of this rollout (the shared prefix not included)

    def to_dict(self) -> dict:
        return {
            "survived": self.survived,
            "fall_time_s": self.fall_time_s,
            "max_dcm_error_m": self.max_dcm_error_m,
            "wall_time_s": self.wall_time_s,
        }

    @classmethod
    def from_dict(cls, d: dict) -> RolloutResult:
        return cls(
            bool(d["survived"]),
            None if d.get("fall_time_s") is None else float(d["fall_time_s"]),
            float(d.get("max_dcm_error_m", 0.0)),
            float(d.get("wall_time_s", 0.0)),
        )


def _walk_to_push(trial: Trial) -> Session:
    session = Session(trial.config, backend=trial.backend)
    session.run(max(0.0, trial.start_s - session.t), stop_on_fall=True)
    return session


def prefix_snapshot(trial: Trial) -> bytes:
    """The session's state walked to the push start (:meth:`Session.save_state`), pickled: every
    rollout of the trial continues from it instead of walking there again (the humanoid's
    prefix is most of a rollout: 4 of 6 s for a push in step 4 of walk_forward).  The whole
    session was pickled before, which the humanoid's MuJoCo model and the robot's lock refused,
    so every humanoid rollout walked its prefix."""
    session = _walk_to_push(trial)
    return pickle.dumps(session.save_state(), protocol=pickle.HIGHEST_PROTOCOL)


def rollout(trial: Trial, snapshot: bytes | None, force: Sequence[float]) -> RolloutResult:
    """Walk on from ``snapshot`` (or from the start) with one push of ``force`` (N, world)."""
    wall = time.perf_counter()
    if snapshot is not None:
        session = Session.from_state(pickle.loads(snapshot))
    else:
        session = _walk_to_push(trial)
    session.push(
        [float(f) for f in force],
        trial.duration_s,
        ramp=trial.ramp_s,
        body=trial.body,
        start=trial.start_s,
    )
    session.run(trial.end_s - session.t, stop_on_fall=True)
    m = session.metrics
    return RolloutResult(
        survived=not m.fell,
        fall_time_s=m.fall_time_s,
        max_dcm_error_m=float(m.max_dcm_error_m),
        wall_time_s=time.perf_counter() - wall,
    )


class Rollouts:
    """Rollouts of one trial with different push forces, in this process.

    Every rollout is identical until the push starts, so the session is simulated to that instant
    once (:func:`prefix_snapshot`) and each force starts from a copy of it (:func:`rollout`).
    """

    def __init__(self, trial: Trial) -> None:
        self.trial = trial
        self.runs = 0
        self.snapshot = prefix_snapshot(trial)

    def run(self, force: Sequence[float]) -> RolloutResult:
        self.runs += 1
        return rollout(self.trial, self.snapshot, force)

    def survives(self, force: Sequence[float]) -> bool:
        """Walk on with one push of ``force`` (N, world); True if not fallen by ``end_s``."""
        return self.run(force).survived


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


class BoundarySearch:
    """Coarse grid over (0, hi], then bisection below the first failing grid point, as a state
    machine: :meth:`ask` hands out the probes the search needs now (the whole grid at once, then
    one bisection midpoint at a time), :meth:`tell` takes their outcomes in any order.

    The probes and the result do not depend on the order of the answers, so a search driven
    concurrently ends exactly where :func:`find_boundary` does.
    """

    def __init__(self, hi: float, *, grid: int = 6, iterations: int = 7) -> None:
        self.hi, self.grid, self.iterations = hi, grid, iterations
        self._points = [hi * (i + 1) / grid for i in range(grid)]
        self._grid_ok: dict[float, bool] = {}
        self._asked: list[float] = []  # handed out, not answered
        self._lo = 0.0
        self._fail: float | None = None
        self._hi_b = hi
        self._above: list[float] = []
        self._mid: float | None = None
        self._bisections = 0
        self.runs = 0
        self.result: Boundary | None = None
        self._phase = "grid"

    @property
    def done(self) -> bool:
        return self.result is not None

    @property
    def max_runs(self) -> int:
        """Upper bound of the probes this search takes (grid + iterations)."""
        return self.grid + self.iterations

    def ask(self) -> list[float]:
        """Probes to run now that were not handed out before (empty: wait for answers)."""
        if self.done or self._asked:
            return []
        if self._phase == "grid" and not self._grid_ok:
            self._asked = list(self._points)
        elif self._phase == "bisect":
            self._mid = 0.5 * (self._lo + self._hi_b)
            self._asked = [self._mid]
        return list(self._asked)

    def tell(self, x: float, ok: bool) -> None:
        """The outcome of probe ``x`` (True: survived)."""
        if x not in self._asked:
            raise ValueError(f"probe {x!r} was not asked (or was answered already)")
        self._asked.remove(x)
        self.runs += 1
        if self._phase == "grid":
            self._grid_ok[x] = ok
            if len(self._grid_ok) == len(self._points):
                self._end_grid()
            return
        if ok:
            self._lo = x
        else:
            self._hi_b = x
        self._bisections += 1
        if self._bisections == self.iterations:
            self.result = Boundary(self._lo, self._hi_b, self._above, self.runs)

    def _end_grid(self) -> None:
        survived = []
        for p in self._points:
            if self._grid_ok[p]:
                survived.append(p)
                if self._fail is None:
                    self._lo = p
            elif self._fail is None:
                self._fail = p  # keep scanning: a survivor above it shows non-monotonicity
        if self._fail is None:
            self.result = Boundary(self._lo, None, [], self.runs)
            return
        self._above = [p for p in survived if p > self._fail]
        self._hi_b = self._fail
        self._phase = "bisect"
        if self.iterations == 0:
            self.result = Boundary(self._lo, self._hi_b, self._above, self.runs)


def find_boundary(
    ok: Callable[[float], bool], hi: float, *, grid: int = 6, iterations: int = 7
) -> Boundary:
    """Coarse grid over (0, hi], then bisection below the first failing grid point.

    ``ok(0)`` is assumed true.  The result's resolution is hi / grid / 2**iterations.
    """
    search = BoundarySearch(hi, grid=grid, iterations=iterations)
    while not search.done:
        for x in search.ask():
            search.tell(x, ok(x))
    assert search.result is not None
    return search.result


def push_window(config: Config, step: int, phase: float) -> tuple[float, float, float]:
    """(push start, lift-off, touchdown) in s for a push at ``phase`` of step ``step``'s single
    support (``step`` 1-based, in the nominal plan)."""
    plan = plan_from_config(config)
    if not 1 <= step <= len(plan.steps):
        raise ValueError(f"step {step}: the preset's plan has steps 1..{len(plan.steps)}")
    t_lift, t_touch = plan.swing_window(step - 1)
    return t_lift + phase * (t_touch - t_lift), t_lift, t_touch
