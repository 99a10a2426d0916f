"""Where rollouts run: in this process (``--jobs 1``, :class:`SerialRunner`) or as Ray tasks, one
rollout per task (:class:`RayRunner`); :func:`~dcmviz.sweep.scheduler.run_cells` feeds them.

Ray: a local instance by default (``ray.init(address="local", num_cpus=jobs)``), or a running
cluster with ``address``.  A task whose worker dies (killed, out of memory, crashed) is retried
up to :data:`MAX_RETRIES` times by Ray; the sweep completes with the same numbers.
"""

from __future__ import annotations

import collections
import logging
import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, Protocol

from dcmviz.sweep.cells import Force, RolloutFn
from dcmviz.sweep.search import (
    RolloutResult,
    Trial,
    prefix_snapshot,
    rollout,
)

MAX_RETRIES = 3  # Ray retries of a task whose worker process died


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
    its pickled state there (Session.save_state) shared through the object store.

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
        self._prefixes: dict[str, Any] = {}  # trial key -> ObjectRef of its pickled state
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
