"""One walking session: preset → plan → walker → backend, with pushes, history and metrics.

The headless runner, the sweeps and the dashboard are thin shells over this object.  It is not
thread-safe by itself: one thread (the simulation loop) calls :meth:`Session.step`; others read
snapshots or post commands through the dashboard's loop.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dcmviz.config import Config, Push
from dcmviz.gait import GaitPlan
from dcmviz.robots import get_spec
from dcmviz.state import MeasuredState, WalkerCommand
from dcmviz.walker import Walker

HISTORY = 4000  # samples kept for live plots (ring buffer)
HISTORY_KEYS = ("t", "xi", "xi_ref", "xi_adj", "v_cmd", "v_ref", "com", "f_ext", "f_hat")


def make_backend(config: Config, backend: str | None = None):
    """The point-mass or MuJoCo backend for a preset (``backend`` overrides sim.backend)."""
    name = backend or config.sim.backend
    if name == "lip":
        from dcmviz.sim.lip import LipBackend

        return LipBackend(config.robot.model, b=config.dcm.b)
    if name == "mujoco":
        from dcmviz.sim.mujoco_sim import MujocoBackend

        return MujocoBackend(config.robot.model)
    raise ValueError(f"sim.backend = {name!r}: allowed 'mujoco' or 'lip'")


@dataclass
class Metrics:
    fell: bool = False
    fall_time_s: float | None = None
    max_dcm_error_m: float = 0.0
    final_dcm_error_m: float = 0.0
    ticks: int = 0
    wall_time_s: float = 0.0


class Session:
    """Owns the walker, the backend, the push schedule and the recorded history."""

    def __init__(
        self,
        config: Config,
        *,
        backend: str | None = None,
        on_tick: Callable[[Session], None] | None = None,
    ) -> None:
        self.backend_name = backend or config.sim.backend
        self.on_tick = on_tick  # e.g. a rerun recorder
        self.backend = None
        self.set_config(config)

    # -- configuration --------------------------------------------------------------------------
    def set_config(self, config: Config, *, backend: str | None = None) -> None:
        """Adopt a new (validated) preset: rebuild backend if the robot changed, then reset."""
        name = backend or self.backend_name
        rebuild = (
            self.backend is None
            or name != self.backend_name
            or config.robot.model != self.config.robot.model
            or (name == "lip" and config.dcm.b != self.config.dcm.b)
        )
        self.config = config
        self.backend_name = name
        if rebuild:
            self.backend = make_backend(config, name)
        self.reset()

    @property
    def plan(self) -> GaitPlan:
        """The walker's current plan (with committed adjustments)."""
        return self.walker.plan

    @property
    def nominal_plan(self) -> GaitPlan:
        """The plan the walker started from, before any step adjustment."""
        return self.walker.nominal_plan

    def reset(self) -> None:
        state = self.backend.reset()
        self.walker = Walker(self.config, mass=self.backend.mass, dt=self.backend.control_dt)
        self.walker.reset(state)
        self.last_state: MeasuredState = state
        self.last_command: WalkerCommand | None = None
        self.pushes: list[Push] = list(self.config.pushes)
        self.metrics = Metrics()
        self._history = {
            k: np.full((HISTORY,) if k == "t" else (HISTORY, 3), np.nan) for k in HISTORY_KEYS
        }
        self._n = 0
        self._applied: dict[str, np.ndarray] = {}

    # -- commands -------------------------------------------------------------------------------
    def push(
        self,
        force,
        duration: float,
        ramp: float = 0.0,
        body: str = "torso",
        start: float | None = None,
    ) -> Push:
        """Schedule a push (validated like a preset push), starting now unless ``start`` given."""
        spec = get_spec(self.config.robot.model)
        if body not in spec.bodies:
            raise ValueError(
                f"body = {body!r}: unknown for {spec.name}; allowed: {', '.join(spec.bodies)}"
            )
        push = Push(
            start=self.t if start is None else start,
            duration=duration,
            force=tuple(float(f) for f in force),
            ramp=ramp,
            body=body,
        )
        self.pushes.append(push)
        return push

    @property
    def t(self) -> float:
        return self.last_state.t

    @property
    def fell(self) -> bool:
        return self.metrics.fell

    def external_force(self) -> dict[str, np.ndarray]:
        """Forces applied this tick by body name (N, world)."""
        return dict(self._applied)

    # -- the loop -------------------------------------------------------------------------------
    def step(self) -> WalkerCommand:
        """One control tick: pushes → walker → backend → metrics."""
        t = self.last_state.t
        forces: dict[str, np.ndarray] = {}
        for push in self.pushes:
            f = np.array(push.force_at(t))
            if np.any(f):
                forces[push.body] = forces.get(push.body, np.zeros(3)) + f
        for body in set(self._applied) | set(forces):
            self.backend.set_external_force(body, forces.get(body, np.zeros(3)))
        self._applied = forces
        command = self.walker.step(self.last_state)
        self.last_command = command
        self.last_state = self.backend.step(command)
        if not self.metrics.fell and self.backend.fell():
            self.metrics.fell = True
            self.metrics.fall_time_s = self.last_state.t
        self._record(command, forces)  # after the fall check: a fall's tick is not a tracking error
        if self.on_tick is not None:
            self.on_tick(self)
        return command

    def run(self, duration: float, *, stop_on_fall: bool = True) -> Metrics:
        """Step until ``duration`` s of simulated time have passed (or the robot fell)."""
        t_end = self.t + duration
        wall = time.perf_counter()
        while self.t < t_end - 1e-9:
            self.step()
            if stop_on_fall and self.metrics.fell:
                break
        self.metrics.wall_time_s += time.perf_counter() - wall
        return self.metrics

    def _record(self, cmd: WalkerCommand, forces: dict[str, np.ndarray]) -> None:
        e = cmd.xi - cmd.xi_ref
        error = math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
        m = self.metrics
        m.ticks += 1
        m.final_dcm_error_m = error
        if not m.fell:
            m.max_dcm_error_m = max(m.max_dcm_error_m, error)
        i = self._n % HISTORY
        h = self._history
        h["t"][i] = cmd.t
        h["xi"][i], h["xi_ref"][i], h["xi_adj"][i] = cmd.xi, cmd.xi_ref, cmd.xi_adj
        h["v_cmd"][i], h["v_ref"][i], h["f_hat"][i] = cmd.v_cmd, cmd.v_ref, cmd.f_hat
        h["com"][i] = self.last_state.com
        h["f_ext"][i] = sum(forces.values(), np.zeros(3))
        self._n += 1

    def history(self) -> dict[str, np.ndarray]:
        """The recorded samples in time order (copies), up to the last HISTORY ticks."""
        n = min(self._n, HISTORY)
        start = self._n % HISTORY if self._n > HISTORY else 0
        idx = (start + np.arange(n)) % HISTORY
        out = {k: v[idx].copy() for k, v in self._history.items()}
        out["dcm_error"] = np.linalg.norm(out["xi"] - out["xi_ref"], axis=1) if n else np.zeros(0)
        return out

    # -- summaries ------------------------------------------------------------------------------
    @property
    def steps_completed(self) -> int:
        return self.walker.steps_completed

    @property
    def step_adjustments(self) -> list[dict[str, float]]:
        return self.walker.step_adjustments

    @property
    def adjusted_target(self):
        """(step index, position) of the footstep being adjusted right now, or None."""
        return self.walker.adjusted_target

    def realised_steps(self):
        return list(self.walker.records)
