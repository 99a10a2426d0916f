"""The two sweep experiments: the push-recovery envelope (largest impulse per push direction and
controller) and the ramp test (largest held force of the preset's ramped push per controller);
their cells run in a process pool."""

from __future__ import annotations

import math
import multiprocessing
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from dcmviz import GRAVITY
from dcmviz.cli import BadInput
from dcmviz.config import Config
from dcmviz.gait import plan_from_config
from dcmviz.session import Session
from dcmviz.sweep.report import ratios
from dcmviz.sweep.search import Rollouts, Trial, find_boundary, push_window

CONTROLLERS: dict[str, dict[str, bool]] = {
    "tracking": {"step_adjustment": False, "observer": False},  # eq. (24)
    "step_adjustment": {"step_adjustment": True, "observer": False},  # eqs. (27)-(35), (40)/(41)
    "step_adjustment+observer": {"step_adjustment": True, "observer": True},  # + eqs. (42)-(49)
}


# ---------------------------------------------------------------------------------------------
# envelope


def _cell(job: tuple[Trial, float, str, float, int, int]) -> dict[str, Any]:
    trial, direction, controller, hi, grid, iterations = job
    unit = np.array([math.cos(direction), math.sin(direction), 0.0])
    wall = time.perf_counter()
    rollouts = Rollouts(trial)
    # search over the impulse J (N·s); the force is J / T_push
    b = find_boundary(
        lambda j: rollouts.survives(unit * (j / trial.duration_s)),
        hi,
        grid=grid,
        iterations=iterations,
    )
    return {
        "direction_deg": round(math.degrees(direction), 6),
        "controller": controller,
        "max_impulse_ns": b.max_ok,
        "max_force_n": b.max_ok / trial.duration_s,
        "first_fail_impulse_ns": b.first_fail,
        "capped": b.capped,
        "non_monotone_ns": b.non_monotone,
        "runs": b.runs,
        "wall_time_s": time.perf_counter() - wall,
    }


def _pool_map(fn: Callable, jobs: list, n_jobs: int) -> list:
    if n_jobs <= 1 or len(jobs) <= 1:
        return [fn(j) for j in jobs]
    method = "fork" if "fork" in multiprocessing.get_all_start_methods() else None
    with multiprocessing.get_context(method).Pool(min(n_jobs, len(jobs))) as pool:
        return pool.map(fn, jobs, chunksize=1)


@dataclass
class SweepSettings:
    backend: str = "lip"
    directions: int = 8
    push_duration_s: float = 0.2
    phase: float = 0.5
    step: int = 4
    settle_steps: float = 3.0
    full: bool = False
    max_impulse_ns: float = 150.0
    grid: int = 6
    iterations: int = 7
    jobs: int = field(default_factory=lambda: os.cpu_count() or 1)
    body: str = "torso"
    controllers: tuple[str, ...] = tuple(CONTROLLERS)
    angles_deg: tuple[float, ...] | None = None  # explicit directions instead of ``directions``

    def direction_angles(self) -> list[float]:
        """Push directions (rad), 0 = +x forward, counter-clockwise."""
        if self.angles_deg is not None:
            return [math.radians(a) for a in self.angles_deg]
        return [2.0 * math.pi * i / self.directions for i in range(self.directions)]


def envelope(config: Config, settings: SweepSettings) -> dict[str, Any]:
    """The push-recovery envelope of a preset: one row per (direction, controller)."""
    base = config.replace(pushes=[])
    start, t_lift, t_touch = push_window(base, settings.step, settings.phase)
    push_end = start + settings.push_duration_s
    plan = plan_from_config(base)
    period = base.gait.t_ss + base.gait.t_ds
    if settings.full:
        end = plan.t_end + base.gait.t_stop
    else:
        end = push_end + settings.settle_steps * period
    jobs = []
    for name in settings.controllers:
        cfg = base.replace(control={**base.control.model_dump(), **CONTROLLERS[name]})
        trial = Trial(cfg, settings.backend, start, settings.push_duration_s, end, settings.body)
        for direction in settings.direction_angles():
            jobs.append(
                (
                    trial,
                    direction,
                    name,
                    settings.max_impulse_ns,
                    settings.grid,
                    settings.iterations,
                )
            )
    wall = time.perf_counter()
    rows = _pool_map(_cell, jobs, settings.jobs)
    wall = time.perf_counter() - wall
    rows.sort(key=lambda r: (r["direction_deg"], settings.controllers.index(r["controller"])))
    return {
        "preset": config.name,
        "robot": config.robot.model,
        "backend": settings.backend,
        "settings": asdict(settings),
        "push_start_s": start,
        "swing_side": plan.steps[settings.step - 1].side,
        "single_support_s": [t_lift, t_touch],
        "run_end_s": end,
        "resolution_ns": settings.max_impulse_ns / settings.grid / 2**settings.iterations,
        "wall_time_s": wall,
        "rows": rows,
        "ratios": ratios(rows),
    }


# ---------------------------------------------------------------------------------------------
# ramp (tug of war) test


def _ramp_cell(job: tuple[Trial, np.ndarray, str, float, int, int]) -> dict[str, Any]:
    trial, unit, controller, hi, grid, iterations = job
    wall = time.perf_counter()
    rollouts = Rollouts(trial)
    b = find_boundary(lambda f: rollouts.survives(unit * f), hi, grid=grid, iterations=iterations)
    return {
        "controller": controller,
        "max_held_force_n": b.max_ok,
        "first_fall_force_n": b.first_fail,
        "capped": b.capped,
        "non_monotone_n": b.non_monotone,
        "runs": b.runs,
        "wall_time_s": time.perf_counter() - wall,
    }


def ramp_test(config: Config, settings: SweepSettings, *, max_force_n: float) -> dict[str, Any]:
    """Bisect the held force of the preset's (first) ramped push for each controller."""
    ramped = [p for p in config.pushes if p.ramp > 0.0]
    if not ramped:
        raise BadInput("--ramp-test: the preset has no ramped push (pushes[*].ramp > 0)")
    push = ramped[0]
    force = np.array(push.force, dtype=float)
    unit = force / np.linalg.norm(force)
    base = config.replace(pushes=[])
    session = Session(base, backend=settings.backend)
    mass = float(session.backend.mass)
    jobs = []
    for name in settings.controllers:
        cfg = base.replace(control={**base.control.model_dump(), **CONTROLLERS[name]})
        trial = Trial(
            cfg,
            settings.backend,
            push.start,
            push.duration,
            config.sim.duration,
            push.body,
            push.ramp,
        )
        jobs.append((trial, unit, name, max_force_n, settings.grid, settings.iterations))
    wall = time.perf_counter()
    rows = _pool_map(_ramp_cell, jobs, settings.jobs)
    for r in rows:
        r["max_held_force_pct_weight"] = 100.0 * r["max_held_force_n"] / (mass * GRAVITY)
    return {
        "preset": config.name,
        "robot": config.robot.model,
        "backend": settings.backend,
        "mass_kg": mass,
        "push": push.model_dump(),
        "preset_force_n": float(np.linalg.norm(force)),
        "run_end_s": config.sim.duration,
        "resolution_n": max_force_n / settings.grid / 2**settings.iterations,
        "wall_time_s": time.perf_counter() - wall,
        "rows": rows,
    }
