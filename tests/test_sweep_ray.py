"""Sweeps on Ray: the same numbers as the serial path, a killed worker's task retried, an
interrupted sweep resumed without redoing finished rollouts, and tuning (Ray Tune + Optuna) that
improves on the starting preset.  One local Ray instance (2 CPUs) for the module; point mass,
coarse searches."""

from __future__ import annotations

import json
import os
import signal
import sys
from pathlib import Path

import pytest

ray = pytest.importorskip("ray")

from dcmviz.config import load_preset  # noqa: E402
from dcmviz.session import Session  # noqa: E402
from dcmviz.sweep import (  # noqa: E402
    Execution,
    RayRunner,
    RolloutStore,
    SweepSettings,
    envelope,
    ray_init,
    rollout,
)
from dcmviz.sweep.tuning import TuneSettings, evaluate, tune_preset, write_tuning  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "presets" / "walk_forward.toml"

SETTINGS = SweepSettings(
    backend="lip",
    angles_deg=(0.0, 90.0, 270.0),
    controllers=("tracking", "step_adjustment"),
    max_impulse_ns=120.0,
    grid=3,
    iterations=3,
    jobs=1,
)


def numbers(result: dict) -> list[dict]:
    """The rows without timings."""
    return [{k: v for k, v in r.items() if k != "wall_time_s"} for r in result["rows"]]


@pytest.fixture(scope="module")
def local_ray():
    started = ray_init(num_cpus=2)
    yield
    if started:
        ray.shutdown()


@pytest.fixture(scope="module")
def serial() -> dict:
    return envelope(load_preset(WALK), SETTINGS)


def walk_with_push(config, start_s: float, end_s: float, force) -> bool:
    """Independent of the sweep code: one session from the start, one push; True if standing."""
    session = Session(config, backend="lip")
    session.push(force, SETTINGS.push_duration_s, start=start_s)
    session.run(end_s, stop_on_fall=True)
    return not session.fell


def test_ray_sweep_equals_serial(local_ray, serial) -> None:
    runner = RayRunner()
    try:
        result = envelope(load_preset(WALK), SETTINGS, Execution(runner=runner))
    finally:
        runner.close()
    assert result["rollouts"]["runner"] == "ray" and serial["rollouts"]["runner"] == "serial"
    assert numbers(result) == numbers(serial)
    assert (
        result["rollouts"]["run"]
        == serial["rollouts"]["run"]
        == sum(r["runs"] for r in serial["rows"])
    )
    # the boundary itself, checked with plain sessions: the largest impulse survives, the
    # smallest failing one falls (lateral push towards the swinging foot, tracking only)
    row = next(
        r for r in serial["rows"] if r["direction_deg"] == 270.0 and r["controller"] == "tracking"
    )
    config = load_preset(WALK).replace(
        pushes=[],
        control={"step_adjustment": False, "observer": False},
    )
    start, end = serial["push_start_s"], serial["run_end_s"]
    force = lambda j: (0.0, -j / SETTINGS.push_duration_s, 0.0)  # noqa: E731
    assert walk_with_push(config, start, end, force(row["max_impulse_ns"]))
    assert not walk_with_push(config, start, end, force(row["first_fail_impulse_ns"]))


def kill_once(marker: Path):
    """A rollout whose first call kills its own worker process (SIGKILL) and leaves its pid in
    ``marker``; later calls (Ray's retry among them) are plain rollouts."""
    path = str(marker)

    def rollout_or_die(trial, snapshot, force):
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            return rollout(trial, snapshot, force)
        os.write(fd, str(os.getpid()).encode())
        os.close(fd)
        os.kill(os.getpid(), signal.SIGKILL)
        raise AssertionError("unreachable")

    return rollout_or_die


def test_killed_worker_is_retried(local_ray, serial, tmp_path: Path) -> None:
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    marker = tmp_path / "killed.pid"
    runner = RayRunner(rollout_fn=kill_once(marker))
    try:
        result = envelope(load_preset(WALK), SETTINGS, Execution(runner=runner))
    finally:
        runner.close()
    pid = int(marker.read_text())
    assert pid != os.getpid()
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)  # the worker really died
    assert numbers(result) == numbers(serial)


class Stop(Exception):
    pass


def test_interrupt_and_resume(local_ray, serial, tmp_path: Path) -> None:
    path = tmp_path / "rollouts.jsonl"
    n_first = 10

    def stop_after(event) -> None:
        if not event.cached and event.done >= n_first:
            raise Stop

    runner = RayRunner()
    try:
        with RolloutStore(path) as store, pytest.raises(Stop):
            envelope(
                load_preset(WALK),
                SETTINGS,
                Execution(runner=runner, store=store, on_result=stop_after),
            )
        lines = [json.loads(line) for line in path.read_text().splitlines()]
        assert sum(rec["kind"] == "rollout" for rec in lines) == n_first
        with RolloutStore(path, resume=True) as store:
            assert store.loaded == n_first
            result = envelope(load_preset(WALK), SETTINGS, Execution(runner=runner, store=store))
    finally:
        runner.close()
    total = serial["rollouts"]["run"]
    assert result["rollouts"]["from_store"] == n_first
    assert result["rollouts"]["run"] == total - n_first  # the finished ones were not redone
    assert numbers(result) == numbers(serial)
    recs = [json.loads(line) for line in path.read_text().splitlines()]
    done = [(r["trial"], tuple(r["force"])) for r in recs if r["kind"] == "rollout"]
    assert len(done) == len(set(done)) == total


def test_tuning_improves_on_the_start(local_ray, tmp_path: Path) -> None:
    config = load_preset(WALK)
    settings = SweepSettings(
        backend="lip", directions=4, max_impulse_ns=150.0, grid=3, iterations=3, jobs=2
    )
    result = tune_preset(config, TuneSettings("weakest", trials=4, seed=0), settings, tmp_path)
    assert len(result["trials"]) == 4
    assert result["best"]["objective"] > result["start"]["objective"]
    paths = write_tuning(result, tmp_path)
    assert [p.name for p in paths] == ["best.toml", "tune.json", "tune.png"]
    best = load_preset(paths[0])
    for key, value in result["best"]["params"].items():
        section, name = key.split(".")
        assert getattr(getattr(best, section), name) == value
    # the written preset, evaluated again serially, scores what the search measured
    again = evaluate(best, "weakest", SweepSettings(**{**settings.__dict__, "jobs": 1}))
    assert again["objective"] == result["best"]["objective"]
    assert (
        again["objective"]
        > evaluate(config, "weakest", SweepSettings(**{**settings.__dict__, "jobs": 1}))[
            "objective"
        ]
    )
