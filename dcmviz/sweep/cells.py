"""The values of a sweep: what a cell searches (:class:`Cell`: a trial and its probes or boundary
search), what one rollout's answer was (:class:`RolloutEvent`) and what a sweep returns
(:class:`CellOutcome`, :class:`SweepRun`)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from dcmviz.sweep.search import Boundary, BoundarySearch, RolloutResult, Trial

Force = tuple[float, float, float]
RolloutFn = Callable[[Trial, "bytes | None", Sequence[float]], RolloutResult]


class Probes:
    """A fixed set of probes, all asked at once (the same interface as BoundarySearch)."""

    def __init__(self, xs: Sequence[float]) -> None:
        self._todo = list(xs)
        self._asked: list[float] = []
        self.outcomes: dict[float, bool] = {}
        self.runs = 0
        self.max_runs = len(self._todo)
        self.result: Boundary | None = None

    @property
    def done(self) -> bool:
        return not self._todo and not self._asked

    def ask(self) -> list[float]:
        out, self._asked, self._todo = self._todo, self._asked + self._todo, []
        return out

    def tell(self, x: float, ok: bool) -> None:
        self._asked.remove(x)
        self.outcomes[x] = ok
        self.runs += 1


@dataclass(frozen=True)
class Cell:
    """One search: push ``trial`` along ``unit`` with force magnitude x / ``divisor`` (N) for the
    searched x (an impulse in N·s with ``divisor`` = T_push, or a force in N with 1).

    ``probes`` given: run exactly those x; otherwise search the boundary on (0, hi].
    ``label`` is carried to the results (direction, controller, map point, ...).
    """

    trial: Trial
    unit: tuple[float, float, float]
    divisor: float = 1.0
    hi: float = 150.0
    grid: int = 6
    iterations: int = 7
    probes: tuple[float, ...] | None = None
    label: dict[str, Any] = field(default_factory=dict, compare=False, hash=False)

    def force(self, x: float) -> Force:
        """The push force (N, world) of probe x."""
        f = x / self.divisor
        return (self.unit[0] * f, self.unit[1] * f, self.unit[2] * f)

    def new_search(self) -> BoundarySearch | Probes:
        if self.probes is not None:
            return Probes(self.probes)
        return BoundarySearch(self.hi, grid=self.grid, iterations=self.iterations)


@dataclass
class CellOutcome:
    cell: Cell
    boundary: Boundary | None  # None for fixed probes
    rollouts: dict[float, RolloutResult]  # by probe x

    @property
    def runs(self) -> int:
        return len(self.rollouts)

    @property
    def rollout_time_s(self) -> float:
        """Summed wall time of this cell's rollouts (as measured when each ran)."""
        return sum(r.wall_time_s for r in self.rollouts.values())


@dataclass(frozen=True)
class RolloutEvent:
    """Passed to ``on_result`` after each answered probe (raise from it to stop the sweep)."""

    index: int  # of the cell in the list given to run_cells
    cell: Cell
    x: float
    result: RolloutResult
    cached: bool  # answered from the store, not run
    boundary: Boundary | None  # set when this probe finished the cell's search
    done: int  # probes answered so far
    total: int  # upper bound of all probes


@dataclass
class SweepRun:
    outcomes: list[CellOutcome]
    run: int  # rollouts run now
    cached: int  # probes answered from the store
    wall_time_s: float
    runner: str
