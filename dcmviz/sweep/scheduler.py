"""The driver of a sweep: :func:`run_cells` runs many cells' searches at once on a runner
(:mod:`.runner`), with results streamed to a :class:`~dcmviz.sweep.store.RolloutStore`.

Each cell (a trial, a push direction, a search) is a :class:`~dcmviz.sweep.search.BoundarySearch`
or a fixed list of probes.  :func:`run_cells` hands each cell's next probes to the runner as soon
as the previous ones are answered, so the bisections of every cell proceed concurrently and all
workers stay busy; probes already in the store are answered from it without running.  Rollouts
are deterministic, so the result does not depend on the runner, the number of workers or the
order in which rollouts finish.
"""

from __future__ import annotations

import collections
import time
from collections.abc import Callable, Sequence

from dcmviz.sweep.cells import Cell, CellOutcome, Force, RolloutEvent, SweepRun
from dcmviz.sweep.runner import Runner
from dcmviz.sweep.search import RolloutResult
from dcmviz.sweep.store import RolloutStore, trial_key


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
