"""Running many searches' rollouts: in this process (``--jobs 1``) or as Ray tasks, one rollout
per task, with results streamed to a :class:`~dcmviz.sweep.store.RolloutStore` as they finish.

Each cell (a trial, a push direction, a search) is a :class:`~dcmviz.sweep.search.BoundarySearch`
or a fixed list of probes.  :func:`run_cells` drives all cells at once: it hands each cell's next
probes to the runner as soon as the previous ones are answered, so the bisections of every cell
proceed concurrently and all workers stay busy; probes already in the store are answered from it
without running.  Rollouts are deterministic, so the result does not depend on the runner, the
number of workers or the order in which rollouts finish.

Ray: a local instance by default (``ray.init(address="local", num_cpus=jobs)``), or a running
cluster with ``address``.  A task whose worker dies (killed, out of memory, crashed) is retried
up to :data:`MAX_RETRIES` times by Ray; the sweep completes with the same numbers.
"""

from __future__ import annotations

import collections
import logging
import os
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Protocol

from dcmviz.sweep.search import (
    Boundary,
    BoundarySearch,
    RolloutResult,
    Trial,
    prefix_snapshot,
    rollout,
)
from dcmviz.sweep.store import RolloutStore, trial_key

MAX_RETRIES = 3  # Ray retries of a task whose worker process died

Force = tuple[float, float, float]
RolloutFn = Callable[[Trial, "bytes | None", Sequence[float]], RolloutResult]


# ---------------------------------------------------------------------------------------------
# cells


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


# ---------------------------------------------------------------------------------------------
# runners


class Runner(Protocol):
    name: str
    max_active: int  # cells driven at once

    def submit(self, key: str, trial: Trial, force: Force) -> None: ...

    def next(self) -> tuple[tuple[str, Force], RolloutResult]: ...

    def release(self, key: str) -> None: ...

    def cancel(self) -> None: ...

    def close(self) -> None: ...


class SerialRunner:
    """Rollouts one after another in this process, cell by cell (no Ray)."""

    name = "serial"
    max_active = 1

    def __init__(self, rollout_fn: RolloutFn = rollout) -> None:
        self._rollout = rollout_fn
        self._queue: collections.deque[tuple[str, Trial, Force]] = collections.deque()
        self._snapshots: dict[str, bytes | None] = {}

    def submit(self, key: str, trial: Trial, force: Force) -> None:
        self._queue.append((key, trial, force))

    def next(self) -> tuple[tuple[str, Force], RolloutResult]:
        key, trial, force = self._queue.popleft()
        if key not in self._snapshots:
            self._snapshots[key] = prefix_snapshot(trial)
        return (key, force), self._rollout(trial, self._snapshots[key], force)

    def release(self, key: str) -> None:
        self._snapshots.pop(key, None)

    def cancel(self) -> None:
        self._queue.clear()

    def close(self) -> None:
        self._snapshots.clear()


def ray_init(num_cpus: int | None = None, address: str | None = None) -> bool:
    """Start a local Ray instance (``address`` None) or connect to a cluster; False if Ray was
    running in this process already (then nothing is started).

    Quiet: no dashboard, workers' output not forwarded, Ray's own log at ERROR, no usage stats
    (unless ``RAY_USAGE_STATS_ENABLED`` says otherwise).  Ray 2.60
    enables token authentication for local instances and says so in a WARNING; it stays on (the
    warning is silenced with the rest of Ray's log).  A cluster gets this checkout's ``dcmviz``
    shipped to its workers (``runtime_env`` ``py_modules``); they need its dependencies.
    """
    # no usage report to Anyscale unless the user asked for it
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    import ray

    if ray.is_initialized():
        return False
    kwargs: dict[str, Any] = {
        "include_dashboard": False,
        "log_to_driver": False,
        "logging_level": logging.ERROR,
    }
    if address is None:
        ray.init(address="local", num_cpus=num_cpus, **kwargs)
    else:
        import dcmviz

        try:
            ray.init(address=address, runtime_env={"py_modules": [dcmviz]}, **kwargs)
        except ConnectionError as err:
            raise ConnectionError(
                f"--address {address}: cannot connect to a Ray cluster there ({err}); a cluster "
                "with token authentication needs RAY_AUTH_MODE=token and its token in "
                "RAY_AUTH_TOKEN (or ~/.ray/auth_token)"
            ) from None
    return True


class RayRunner:
    """One Ray task per rollout; the prefix of each trial (walk to the push) is one task too,
    its pickled session shared through the object store.

    Uses the Ray instance of this process if there is one (e.g. inside a Ray Tune trial),
    otherwise starts one (:func:`ray_init`) and stops it in :meth:`close`.
    """

    name = "ray"

    def __init__(
        self,
        num_cpus: int | None = None,
        address: str | None = None,
        *,
        rollout_fn: RolloutFn = rollout,
        max_retries: int = MAX_RETRIES,
    ) -> None:
        import ray

        self._ray = ray
        self._own = ray_init(num_cpus, address)
        self.cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))
        self.max_active = max(4, 4 * self.cpus)
        options = {"num_cpus": 1, "max_retries": max_retries, "retry_exceptions": False}
        self._prefix_task = ray.remote(**options)(prefix_snapshot)
        self._rollout_task = ray.remote(**options)(rollout_fn)
        self._prefixes: dict[str, Any] = {}  # trial key -> ObjectRef of the pickled session
        self._pending: dict[Any, tuple[str, Force]] = {}  # ObjectRef -> (trial key, force)

    def submit(self, key: str, trial: Trial, force: Force) -> None:
        if key not in self._prefixes:
            self._prefixes[key] = self._prefix_task.remote(trial)
        ref = self._rollout_task.remote(trial, self._prefixes[key], force)
        self._pending[ref] = (key, force)

    def next(self) -> tuple[tuple[str, Force], RolloutResult]:
        ready, _ = self._ray.wait(list(self._pending), num_returns=1)
        token = self._pending.pop(ready[0])
        return token, self._ray.get(ready[0])

    def release(self, key: str) -> None:
        self._prefixes.pop(key, None)  # the object store frees it once no task needs it

    def cancel(self) -> None:
        for ref in list(self._pending):
            try:
                self._ray.cancel(ref)
            except Exception:  # noqa: BLE001 - finished or lost already
                pass
        self._pending.clear()

    def close(self) -> None:
        self.cancel()
        self._prefixes.clear()
        if self._own:
            self._ray.shutdown()
            self._own = False


def make_runner(jobs: int = 1, address: str | None = None) -> SerialRunner | RayRunner:
    """Serial for ``jobs`` 1 without an address, otherwise Ray (local with ``jobs`` CPUs)."""
    if address is None and jobs <= 1:
        return SerialRunner()
    return RayRunner(None if address is not None else jobs, address)


@contextmanager
def open_runner(jobs: int = 1, address: str | None = None) -> Iterator[SerialRunner | RayRunner]:
    runner = make_runner(jobs, address)
    try:
        yield runner
    finally:
        runner.close()


# ---------------------------------------------------------------------------------------------
# the driver


def run_cells(
    cells: Sequence[Cell],
    runner: Runner,
    store: RolloutStore | None = None,
    *,
    progress: bool = False,
    on_result: Callable[[RolloutEvent], None] | None = None,
    desc: str = "rollouts",
) -> SweepRun:
    """Run the searches of all ``cells`` to the end; rollouts found in ``store`` are not run,
    new ones are added to it as they finish.  ``progress`` shows a tqdm bar on stderr (rollouts
    done, rate, time left; the total is an upper bound that shrinks when a search ends early).
    An exception from ``on_result`` (or a KeyboardInterrupt) cancels the rollouts in flight and
    propagates; the finished ones stay in the store."""
    wall = time.perf_counter()
    store = store if store is not None else RolloutStore()
    keys = [trial_key(c.trial) for c in cells]
    searches = [c.new_search() for c in cells]
    rollouts: list[dict[float, RolloutResult]] = [{} for _ in cells]
    remaining = collections.Counter(keys)  # unfinished cells per trial
    total = sum(s.max_runs for s in searches)
    counts = {"done": 0, "run": 0, "cached": 0}
    bar = None

    def finish(i: int) -> None:
        nonlocal total
        total -= searches[i].max_runs - searches[i].runs
        if bar is not None:
            bar.total = total
            bar.refresh()
        remaining[keys[i]] -= 1
        if remaining[keys[i]] == 0:
            runner.release(keys[i])

    def feed(i: int, x: float, result: RolloutResult, cached: bool) -> None:
        rollouts[i][x] = result
        searches[i].tell(x, result.survived)
        counts["done"] += 1
        counts["cached" if cached else "run"] += 1
        if searches[i].done:
            finish(i)
        if bar is not None:
            bar.update(1)
        if on_result is not None:
            boundary = searches[i].result if searches[i].done else None
            on_result(RolloutEvent(i, cells[i], x, result, cached, boundary, counts["done"], total))

    def advance(i: int) -> list[float]:
        """Answer cell i's probes from the store while possible; the probes left to run."""
        while not searches[i].done:
            xs = searches[i].ask()
            if not xs:
                return []  # waiting for probes in flight
            need = []
            for x in xs:
                cached = store.get(keys[i], cells[i].force(x))
                if cached is not None:
                    feed(i, x, cached, True)
                else:
                    need.append(x)
            if need:
                return need
        return []

    inflight: dict[tuple[str, Force], list[tuple[int, float]]] = {}

    def submit(i: int, xs: list[float]) -> None:
        for x in xs:
            token = (keys[i], cells[i].force(x))
            if token not in inflight:
                inflight[token] = []
                runner.submit(keys[i], cells[i].trial, token[1])
            inflight[token].append((i, x))

    try:
        todo: collections.deque[int] = collections.deque()
        first: dict[int, list[float]] = {}
        for i in range(len(cells)):  # replay the store: counts finished work before the bar
            need = advance(i)
            if not searches[i].done:
                first[i] = need
                todo.append(i)
        if progress:
            from tqdm import tqdm

            bar = tqdm(
                total=total,
                initial=counts["done"],
                desc=desc,
                unit="rollout",
                dynamic_ncols=True,
                smoothing=0.1,
            )
        active = 0
        while todo or inflight:
            while todo and active < runner.max_active:
                i = todo.popleft()
                active += 1
                submit(i, first.pop(i))
            token, result = runner.next()
            waiting = inflight.pop(token)
            store.add(token[0], cells[waiting[0][0]].trial, token[1], result)
            for i, x in waiting:
                feed(i, x, result, False)
                if not searches[i].done:
                    submit(i, advance(i))
                if searches[i].done:
                    active -= 1
    except BaseException:
        runner.cancel()
        raise
    finally:
        if bar is not None:
            bar.close()
    outcomes = [
        CellOutcome(c, s.result, dict(sorted(r.items())))
        for c, s, r in zip(cells, searches, rollouts, strict=True)
    ]
    return SweepRun(
        outcomes, counts["run"], counts["cached"], time.perf_counter() - wall, runner.name
    )
