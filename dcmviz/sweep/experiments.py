"""The sweep experiments: the push-recovery envelope (largest impulse per push direction and
controller), the ramp test (largest held force of the preset's ramped push per controller), and
the fixed-push probes behind the tracking objective.  Each builds :class:`~dcmviz.sweep.cells.Cell`
searches and runs them with :func:`~dcmviz.sweep.scheduler.run_cells` (serially or on Ray)."""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from dcmviz import GRAVITY
from dcmviz.config import Config, ControlSection
from dcmviz.gait import plan_from_config
from dcmviz.robots import load_robot
from dcmviz.sweep.bounds import crossover_bound, stance_edge_bound, swing_bound
from dcmviz.sweep.cells import Cell, CellOutcome, RolloutEvent, SweepRun
from dcmviz.sweep.report import ratios
from dcmviz.sweep.runner import Runner, make_runner
from dcmviz.sweep.scheduler import run_cells
from dcmviz.sweep.search import Trial, push_window
from dcmviz.sweep.store import RolloutStore

CONTROLLERS: dict[str, dict[str, bool]] = {
    "tracking": {"step_adjustment": False, "observer": False},  # eq. (24)
    "step_adjustment": {"step_adjustment": True, "observer": False},  # eqs. (27)-(35), (40)/(41)
    "step_adjustment+observer": {"step_adjustment": True, "observer": True},  # + eqs. (42)-(49)
}
PRESET_CONTROLLER = "preset"  # the preset's own [control] flags, unchanged
# recovery strategies (control.recovery) as controllers: step adjustment on, observer off
STRATEGIES: tuple[str, ...] = ControlSection.model_fields["recovery"].annotation.__args__


def controller_flags(name: str) -> dict:
    """The [control] keys controller ``name`` sets: one of CONTROLLERS, or a recovery strategy
    (``--strategies``) with step adjustment on and the observer off."""
    if name in CONTROLLERS:
        return CONTROLLERS[name]
    if name in STRATEGIES:
        return {"step_adjustment": True, "observer": False, "recovery": name}
    raise ValueError(f"controller {name!r}: allowed {', '.join([*CONTROLLERS, *STRATEGIES])}")


def with_controller(config: Config, name: str) -> Config:
    """``config`` with the step adjustment / observer (/ recovery) keys of controller ``name``."""
    if name == PRESET_CONTROLLER:
        return config
    return config.replace(control=controller_flags(name))


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
    jobs: int = field(default_factory=lambda: os.cpu_count() or 1)  # 1: serial, no Ray
    body: str = "torso"
    controllers: tuple[str, ...] = tuple(CONTROLLERS)
    angles_deg: tuple[float, ...] | None = None  # explicit directions instead of ``directions``
    address: str | None = None  # a Ray cluster; None: a local instance (or serial for jobs 1)

    def direction_angles(self) -> list[float]:
        """Push directions (rad), 0 = +x forward, counter-clockwise."""
        if self.angles_deg is not None:
            return [math.radians(a) for a in self.angles_deg]
        return [2.0 * math.pi * i / self.directions for i in range(self.directions)]


@dataclass(frozen=True)
class Execution:
    """How cells run: a runner (None: made from the settings and closed after), where finished
    rollouts go, a progress bar, a callback per answered probe."""

    runner: Runner | None = None
    store: RolloutStore | None = None
    progress: bool = False
    on_result: Callable[[RolloutEvent], None] | None = None


@contextmanager
def _runner(settings: SweepSettings, execution: Execution) -> Iterator[Runner]:
    if execution.runner is not None:
        yield execution.runner
        return
    runner = make_runner(settings.jobs, settings.address)
    try:
        yield runner
    finally:
        runner.close()


def run(
    cells: list[Cell], settings: SweepSettings, execution: Execution | None, desc: str
) -> SweepRun:
    """Run ``cells`` as ``execution`` says (default: serial or local Ray per ``settings.jobs``)."""
    execution = execution or Execution()
    with _runner(settings, execution) as runner:
        return run_cells(
            cells,
            runner,
            execution.store,
            progress=execution.progress,
            on_result=execution.on_result,
            desc=desc,
        )


# ---------------------------------------------------------------------------------------------
# envelope


@dataclass(frozen=True)
class PushWindow:
    start_s: float
    lift_s: float
    touch_s: float
    end_s: float
    swing_side: str


def envelope_window(config: Config, settings: SweepSettings) -> PushWindow:
    """When the envelope's pushes start and when its rollouts end, for this preset."""
    start, t_lift, t_touch = push_window(config, settings.step, settings.phase)
    plan = plan_from_config(config)
    if settings.full:
        end = plan.t_end + config.gait.t_stop
    else:
        period = config.gait.t_ss + config.gait.t_ds
        end = start + settings.push_duration_s + settings.settle_steps * period
    return PushWindow(start, t_lift, t_touch, end, plan.steps[settings.step - 1].side)


def envelope_cells(
    config: Config, settings: SweepSettings, label: dict[str, Any] | None = None
) -> tuple[list[Cell], PushWindow]:
    """One boundary search over the impulse J (N·s; force J / T_push) per controller and
    direction."""
    base = config.replace(pushes=[])
    window = envelope_window(base, settings)
    cells = []
    for name in settings.controllers:
        trial = Trial(
            with_controller(base, name),
            settings.backend,
            window.start_s,
            settings.push_duration_s,
            window.end_s,
            settings.body,
        )
        for direction in settings.direction_angles():
            unit = (math.cos(direction), math.sin(direction), 0.0)
            cells.append(
                Cell(
                    trial,
                    unit,
                    settings.push_duration_s,
                    settings.max_impulse_ns,
                    settings.grid,
                    settings.iterations,
                    label={
                        **(label or {}),
                        "direction_deg": round(math.degrees(direction), 6),
                        "controller": name,
                    },
                )
            )
    return cells, window


def envelope_row(outcome: CellOutcome) -> dict[str, Any]:
    """One envelope row: the largest surviving impulse of one (direction, controller) cell."""
    b = outcome.boundary
    assert b is not None
    duration = outcome.cell.trial.duration_s
    return {
        **outcome.cell.label,
        "max_impulse_ns": b.max_ok,
        "max_force_n": b.max_ok / duration,
        "first_fail_impulse_ns": b.first_fail,
        "capped": b.capped,
        "non_monotone_ns": b.non_monotone,
        "runs": b.runs,
        "wall_time_s": outcome.rollout_time_s,
    }


def envelope_header(config: Config, settings: SweepSettings, window: Any) -> dict[str, Any]:
    """The fields that name an envelope: preset, robot, backend, settings and the push window."""
    return {
        "preset": config.name,
        "robot": config.robot.model,
        "backend": settings.backend,
        "settings": asdict(settings),
        "push_start_s": window.start_s,
        "swing_side": window.swing_side,
    }


def envelope(
    config: Config, settings: SweepSettings, execution: Execution | None = None
) -> dict[str, Any]:
    """The push-recovery envelope of a preset: one row per (direction, controller)."""
    cells, window = envelope_cells(config, settings)
    sweep = run(cells, settings, execution, "envelope")
    rows = [envelope_row(o) for o in sweep.outcomes]
    order = {name: i for i, name in enumerate(settings.controllers)}
    rows.sort(key=lambda r: (r["direction_deg"], order[r["controller"]]))
    return {
        **envelope_header(config, settings, window),
        "single_support_s": [window.lift_s, window.touch_s],
        "run_end_s": window.end_s,
        "resolution_ns": settings.max_impulse_ns / settings.grid / 2**settings.iterations,
        "wall_time_s": sweep.wall_time_s,
        "rollouts": _counts(sweep),
        "rows": rows,
        "ratios": ratios(rows),
        "stance_edge_bound_ns": stance_edge_bounds(config, settings),
        # a humanoid: the same bound with the push's moment taken by the trunk, not the feet
        "stance_edge_bound_trunk_ns": (
            stance_edge_bounds(
                config, settings, functools.partial(stance_edge_bound, moment_at_feet=False)
            )
            if settings.backend != "lip"
            else {}
        ),
        "crossover_bound_ns": stance_edge_bounds(config, settings, crossover_bound),
        # without crossing, the stance foot stepping out once the other is down
        "swing_bound_ns": stance_edge_bounds(config, settings, swing_bound),
    }


def stance_edge_bounds(
    config: Config, settings: SweepSettings, bound=stance_edge_bound
) -> dict[str, float]:
    """Per direction (°) with a part towards the stance foot, the impulse no strategy without
    crossing steps can exceed (dcmviz.sweep.bounds), or another ``bound`` of that module
    (``crossover_bound``: with a crossed footstep)."""
    out = {}
    for angle in settings.direction_angles():
        value = bound(
            config,
            settings.step,
            settings.phase,
            settings.push_duration_s,
            angle,
            backend=settings.backend,
            body=settings.body,
        )
        if value is not None:
            out[f"{math.degrees(angle):.1f}"] = round(value, 2)
    return out


def _counts(sweep: SweepRun) -> dict[str, Any]:
    return {"run": sweep.run, "from_store": sweep.cached, "runner": sweep.runner}


# ---------------------------------------------------------------------------------------------
# fixed pushes (the tracking objective)


def probe_cells(config: Config, settings: SweepSettings, impulse_ns: float) -> list[Cell]:
    """One rollout per controller and direction with a push of ``impulse_ns`` (N·s)."""
    cells, _ = envelope_cells(config, settings)
    return [Cell(c.trial, c.unit, c.divisor, probes=(impulse_ns,), label=c.label) for c in cells]


# ---------------------------------------------------------------------------------------------
# ramp (tug of war) test


def ramp_test(
    config: Config,
    settings: SweepSettings,
    *,
    max_force_n: float,
    execution: Execution | None = None,
) -> dict[str, Any]:
    """Bisect the held force of the preset's (first) ramped push for each controller."""
    ramped = [p for p in config.pushes if p.ramp > 0.0]
    if not ramped:
        raise ValueError("ramp test: the preset has no ramped push (pushes[*].ramp > 0)")
    push = ramped[0]
    force = np.array(push.force, dtype=float)
    unit = tuple(float(u) for u in force / np.linalg.norm(force))
    base = config.replace(pushes=[])
    mass = load_robot(config.robot.model).spec.mass_kg
    cells = []
    for name in settings.controllers:
        trial = Trial(
            with_controller(base, name),
            settings.backend,
            push.start,
            push.duration,
            config.sim.duration,
            push.body,
            push.ramp,
        )
        cells.append(
            Cell(
                trial,
                unit,
                1.0,
                max_force_n,
                settings.grid,
                settings.iterations,
                label={"controller": name},
            )
        )
    sweep = run(cells, settings, execution, "ramp test")
    rows = []
    for o in sweep.outcomes:
        b = o.boundary
        assert b is not None
        rows.append(
            {
                "controller": o.cell.label["controller"],
                "max_held_force_n": b.max_ok,
                "first_fall_force_n": b.first_fail,
                "capped": b.capped,
                "non_monotone_n": b.non_monotone,
                "runs": b.runs,
                "wall_time_s": o.rollout_time_s,
                "max_held_force_pct_weight": 100.0 * b.max_ok / (mass * GRAVITY),
            }
        )
    return {
        "preset": config.name,
        "robot": config.robot.model,
        "backend": settings.backend,
        "mass_kg": mass,
        "push": push.model_dump(),
        "preset_force_n": float(np.linalg.norm(force)),
        "run_end_s": config.sim.duration,
        "resolution_n": max_force_n / settings.grid / 2**settings.iterations,
        "wall_time_s": sweep.wall_time_s,
        "rollouts": _counts(sweep),
        "rows": rows,
    }
