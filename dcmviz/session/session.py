"""One walking session: preset → plan → walker → backend, with pushes, history and metrics.

The headless runner, the sweeps and the dashboard are thin shells over this object: they call
:meth:`Session.step`, post commands (:meth:`Session.push`, :meth:`Session.set_config`) and read
the per-tick record :meth:`Session.tick` (a frozen :class:`~dcmviz.session.tick.Tick`), or subscribe to
it (:meth:`Session.subscribe`).  Nothing outside reaches into the walker or the backend.

It is not thread-safe by itself: one thread (the simulation loop) calls :meth:`Session.step`;
others read ticks or post commands through the dashboard's loop.
"""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from dcmviz.config import Config, Push
from dcmviz.gait import GaitPlan
from dcmviz.gait.terrain import Terrain, terrain_of
from dcmviz.robots import Robot, RobotSpec, load_robot
from dcmviz.session.tick import AppliedPush, Pull, Tick
from dcmviz.sim.backend import Backend
from dcmviz.walker import MeasuredState, Walker, WalkerCommand

Subscriber = Callable[[Tick], None]

REALISED_IN_TICK = 64  # latest landed footsteps a Tick carries (its cost must not grow with time)
HISTORY = 4000  # samples kept for live plots (ring buffer)
PUSHES_KEPT = 256  # pushes remembered (an endless walk pushed every few seconds keeps its latest)
HISTORY_KEYS = ("t", "xi", "xi_ref", "xi_adj", "v_cmd", "v_ref", "com", "f_ext", "f_hat")
PULL_MAX_N = 5000.0  # a spring pull is capped like a preset push's force


def make_backend(
    config: Config, robot: Robot, backend: str | None = None, terrain: Terrain | None = None
) -> Backend:
    """The point-mass or MuJoCo backend for a preset's ``robot`` (``backend`` overrides
    sim.backend) on its ``terrain`` (default: the preset's).

    Both stand at the robot's own CoM height: the controller's b may differ from it, and the
    point mass shows what that does just as the humanoid would.
    """
    name = backend or config.sim.backend
    terrain = terrain if terrain is not None else terrain_of(config.terrain)
    if name == "lip":
        from dcmviz.sim.lip import LipBackend

        return LipBackend(robot, terrain=terrain)
    if name == "mujoco":
        from dcmviz.sim.mujoco_sim import MujocoBackend

        return MujocoBackend(robot, terrain=terrain)
    raise ValueError(f"sim.backend = {name!r}: allowed 'mujoco' or 'lip'")


@dataclass(frozen=True)
class SessionState:
    """A session after one tick, everything it needs to continue from there exactly
    (:meth:`Session.save_state`, :meth:`Session.restore_state`).  Opaque to shells."""

    config: Config
    backend: Any  # the backend's own state (get_state)
    owner: int  # id of the backend it came from: a state restores into that backend only
    walker: Walker  # a private copy
    last_state: MeasuredState
    last_command: WalkerCommand | None
    pushes: tuple[Push, ...]
    pending: tuple[Push, ...]
    applied: dict[str, np.ndarray]
    metrics: Metrics
    ticks: int
    backend_name: str = "mujoco"  # "lip" | "mujoco": what :meth:`Session.from_state` builds


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
        on_tick: Subscriber | None = None,
    ) -> None:
        self.backend_name = backend or config.sim.backend
        self._subscribers: list[Subscriber] = [] if on_tick is None else [on_tick]
        self.backend: Backend | None = None
        self.config: Config | None = None
        self.set_config(config)

    # -- configuration --------------------------------------------------------------------------
    def set_config(self, config: Config, *, backend: str | None = None) -> str:
        """Adopt a new (validated) preset; returns what that did, in words for a status line.

        A change of gains only (``[control]``: k_ξ, k_F, step adjustment, its limit, observer)
        acts on the running walk from the next tick: ``"gains changed (walk continues)"``.
        Anything else restarts the walk (and rebuilds the backend for another robot or backend):
        ``"restarted: <sections> changed"``.
        """
        name = backend or self.backend_name
        old = self.config
        if old is not None and self.backend is not None and name == self.backend_name:
            changed = [k for k in ("robot", "gait", "dcm", "sim", "pushes", "terrain")
                       if getattr(config, k) != getattr(old, k)]  # fmt: skip
            if not changed:
                self.config = config
                self.walker.set_config(config, self.last_state)
                return "gains changed (walk continues)" if config.control != old.control else ""
        else:
            changed = ["backend"] if old is not None else []
        rebuild = (
            self.backend is None
            or name != self.backend_name
            or config.robot.model != old.robot.model
            or config.terrain != old.terrain
        )
        self.config = config
        self.backend_name = name
        if rebuild:
            self.robot = load_robot(config.robot.model)  # built once per process and file
            self.terrain = terrain_of(config.terrain)
            self.backend = make_backend(config, self.robot, name, self.terrain)
        self.reset()
        return f"restarted: {', '.join(changed)} changed" if changed else "started"

    @property
    def plan(self) -> GaitPlan:
        """The walker's current plan (with committed adjustments): the plan walked."""
        return self.walker.status.plan

    @property
    def plan_version(self) -> int:
        """Changes whenever the walked plan does (reset, touchdown commit, replanning)."""
        return self.walker.status.plan_version

    @property
    def nominal_plan(self) -> GaitPlan:
        """The plan the walker started from, before any step adjustment."""
        return self.walker.status.nominal_plan

    def reset(self) -> None:
        state = self.backend.reset()
        version = self.plan_version if getattr(self, "walker", None) else 0
        self.walker = Walker(  # plan versions keep increasing across resets
            self.config, self.robot, mass=self.backend.mass, dt=self.backend.control_dt,
            terrain=self.terrain, plan_version=version,
        )  # fmt: skip
        self.walker.reset(state)
        self.last_state: MeasuredState = state
        self.last_command: WalkerCommand | None = None
        self.pushes: list[Push] = list(self.config.pushes)  # this walk's (the last PUSHES_KEPT)
        self._pending: list[Push] = list(self.pushes)  # those not over yet (cost per tick)
        self.metrics = Metrics()
        self._tick: Tick | None = None
        self._ticks = 0
        self._history = {
            k: np.full((HISTORY,) if k == "t" else (HISTORY, 3), np.nan) for k in HISTORY_KEYS
        }
        self._n = 0
        self._applied: dict[str, np.ndarray] = {}
        self._records_seen: tuple | None = None
        self._records_recent: tuple = ()
        self._pull: Pull | None = None
        self._pull_last: np.ndarray | None = None  # the pulled body's point at the last tick

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
        spec = self.robot.spec
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
        if len(self.pushes) > PUSHES_KEPT:
            del self.pushes[:-PUSHES_KEPT]
        self._pending.append(push)
        return push

    def pull(self, body: str, target, stiffness: float, damping: float = 0.0, grab=None) -> Pull:
        """Pull ``body`` towards ``target`` (m, world) with a spring of ``stiffness`` N/m and
        ``damping`` N·s/m from the next tick on (MuJoCo's viewer's perturbation): each tick the
        body is pushed with k (target − p) − c ṗ (at most PULL_MAX_N), p the point ``grab``
        (m, world, now; default the body's origin) moving with the body.  Calling it again
        moves the target (and keeps the grab point unless given); :meth:`release` lets go."""
        spec = self.robot.spec
        if body not in spec.bodies:
            raise ValueError(
                f"body = {body!r}: unknown for {spec.name}; allowed: {', '.join(spec.bodies)}"
            )
        target = np.array(target, float)
        if target.shape != (3,) or not np.all(np.isfinite(target)):
            raise ValueError(f"target = {target!r}: must be 3 finite numbers (m)")
        if not (math.isfinite(stiffness) and stiffness > 0.0):
            raise ValueError(f"stiffness = {stiffness!r}: must be > 0 N/m")
        if not (math.isfinite(damping) and damping >= 0.0):
            raise ValueError(f"damping = {damping!r}: must be ≥ 0 N·s/m")
        if self._pull is None or self._pull.body != body:
            self._pull_last = None
            offset = np.zeros(3)
        else:
            offset = self._pull.offset
        if grab is not None:
            grab = np.array(grab, float)
            if grab.shape != (3,) or not np.all(np.isfinite(grab)):
                raise ValueError(f"grab = {grab!r}: must be 3 finite numbers (m)")
            offset = grab - np.array(self.backend.body_position(body), float)
        self._pull = Pull(body, target, float(stiffness), float(damping), offset)
        return self._pull

    def release(self) -> None:
        """End a spring pull (:meth:`pull`)."""
        self._pull = None
        self._pull_last = None

    def _pull_force(self, dt: float) -> np.ndarray:
        pull = self._pull
        p = np.array(self.backend.body_position(pull.body), float) + pull.offset
        v = np.zeros(3) if self._pull_last is None else (p - self._pull_last) / dt
        self._pull_last = p
        f = pull.stiffness * (pull.target - p) - pull.damping * v
        n = float(np.linalg.norm(f))
        return f * (PULL_MAX_N / n) if n > PULL_MAX_N else f

    @property
    def t(self) -> float:
        return self.last_state.t

    @property
    def spec(self) -> RobotSpec:
        """The robot's planning facts (feet, reach, push bodies)."""
        return self.backend.spec

    @property
    def mass(self) -> float:
        """kg, of the simulated robot."""
        return float(self.backend.mass)

    @property
    def fell(self) -> bool:
        return self.metrics.fell

    def external_force(self) -> dict[str, np.ndarray]:
        """Forces applied this tick by body name (N, world)."""
        return dict(self._applied)

    # -- the loop -------------------------------------------------------------------------------
    def step(self) -> WalkerCommand:
        """One control tick: pushes → walker → backend → metrics."""
        return self._step(None, notify=True)

    def _step(self, given: Mapping[str, np.ndarray] | None, notify: bool) -> WalkerCommand:
        t = self.last_state.t
        forces: dict[str, np.ndarray] = {}
        if given is not None:  # a replay: the forces recorded for this tick
            forces = {b: np.array(f, float) for b, f in given.items()}
        else:
            if self._pending and any(t >= p.start + p.duration for p in self._pending):
                self._pending = [p for p in self._pending if t < p.start + p.duration]
            for push in self._pending:
                f = np.array(push.force_at(t))
                if np.any(f):
                    forces[push.body] = forces.get(push.body, np.zeros(3)) + f
            if self._pull is not None:
                body = self._pull.body
                forces[body] = forces.get(body, np.zeros(3)) + self._pull_force(
                    self.backend.control_dt
                )
        if forces or self._applied:  # most ticks push nothing and had nothing to clear
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
        self._ticks += 1
        self._tick = None
        if notify and self._subscribers:
            tick = self.tick()
            for subscriber in list(self._subscribers):
                subscriber(tick)
        return command

    # -- the per-tick record --------------------------------------------------------------------
    def subscribe(self, subscriber: Subscriber) -> Callable[[], None]:
        """Call ``subscriber(tick)`` after every tick; returns the function that unsubscribes."""
        self._subscribers.append(subscriber)

        def unsubscribe() -> None:
            if subscriber in self._subscribers:
                self._subscribers.remove(subscriber)

        return unsubscribe

    @property
    def subscribers(self) -> tuple[Subscriber, ...]:
        return tuple(self._subscribers)

    def tick(self) -> Tick | None:
        """The record of the last tick (built once, on request); None before the first step."""
        if self._tick is None and self.last_command is not None:
            self._tick = self._make_tick()
        return self._tick

    def _make_tick(self) -> Tick:
        status, backend, cmd = self.walker.status, self.backend, self.last_command
        pushes = tuple(
            AppliedPush(body, f.copy(), np.array(backend.body_position(body), float))
            for body, f in self._applied.items()
        )
        adjusted = status.adjusted
        plan = status.plan
        adjusted_step = recovery_step = None
        if adjusted is not None and 0 <= adjusted[0] < len(plan.steps):
            adjusted_step = plan.steps[adjusted[0]].moved(np.array(adjusted[1], float))
        contacts = tuple(backend.contacts())
        cop = None
        if contacts:
            weight = np.array([max(float(f[2]), 0.0) for _, f in contacts])
            points = np.array([p for p, _ in contacts])
            cop = weight @ points / weight.sum() if weight.sum() > 1e-9 else None
        second = status.following
        if second is not None and 0 <= second[0] < len(plan.steps):
            nominal = plan.steps[second[0]]
            if float(np.linalg.norm(np.asarray(second[1]) - nominal.position)) > 1e-3:
                recovery_step = nominal.moved(np.array(second[1], float))
        return Tick(
            index=self._ticks,
            t=float(cmd.t),
            robot=self.robot,
            backend=backend.name,
            state=self.last_state,
            command=cmd,
            plan=plan,
            plan_version=status.plan_version,
            nominal_plan=status.nominal_plan,
            adjusted_index=-1 if adjusted_step is None else int(adjusted[0]),
            adjusted_step=adjusted_step,
            recovery_step=recovery_step,
            realised_steps=self._recent(status.records),
            steps_completed=status.steps_completed,
            next_step_index=status.next_step_index,
            pushes=pushes,
            f_ext=sum((p.force for p in pushes), np.zeros(3)),
            f_hat=np.array(cmd.f_hat, float),
            pose=backend.robot_pose(),
            fell=self.metrics.fell,
            done=bool(cmd.done),
            contacts=contacts,
            cop=cop,
            physics=backend.physics_state(),
            pull=self._pull,
            swing_path=status.swing_path,
        )

    def _recent(self, records: tuple) -> tuple:
        """The latest REALISED_IN_TICK landed footsteps, one tuple from one landing to the
        next (a Tick's cost must not grow with the steps walked; readers may compare by id)."""
        if records is not self._records_seen:
            self._records_seen, self._records_recent = records, records[-REALISED_IN_TICK:]
        return self._records_recent

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
        ex, ey, ez = (cmd.xi - cmd.xi_ref).tolist()
        error = math.sqrt(ex * ex + ey * ey + ez * ez)
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
        total = h["f_ext"][i]  # 0 + each force in turn, in place (as sum() from zeros)
        total.fill(0.0)
        for force in forces.values():
            total += force
        self._n += 1

    def history(self) -> dict[str, np.ndarray]:
        """The recorded samples in time order (copies), up to the last HISTORY ticks."""
        n = min(self._n, HISTORY)
        start = self._n % HISTORY if self._n > HISTORY else 0
        idx = (start + np.arange(n)) % HISTORY
        out = {k: v[idx].copy() for k, v in self._history.items()}
        out["dcm_error"] = np.linalg.norm(out["xi"] - out["xi_ref"], axis=1) if n else np.zeros(0)
        return out

    # -- resuming from a tick -------------------------------------------------------------------
    def save_state(self) -> SessionState:
        """The session after its last tick, to continue from there later (:meth:`restore_state`):
        the backend's state, a copy of the walker, the pushes and the metrics.  A spring pull
        is not part of it (it is the user's hand, not the walk)."""
        return SessionState(
            config=self.config, backend=self.backend.get_state(), owner=id(self.backend),
            walker=self.walker.copy(), last_state=self.last_state,
            last_command=self.last_command, pushes=tuple(self.pushes),
            pending=tuple(self._pending),
            applied={b: f.copy() for b, f in self._applied.items()},
            metrics=copy.copy(self.metrics), ticks=self._ticks,
            backend_name=self.backend_name,
        )  # fmt: skip

    @classmethod
    def from_state(cls, state: SessionState) -> Session:
        """A new session that continues from ``state`` exactly as the one that saved it would:
        built from the state's preset (its robot, terrain and backend kind), then given the
        state.  A state pickles (the robot as its name, :meth:`Robot.__reduce__`), so a walk can
        go on in another process: the sweep walks each trial to its push once and every rollout
        continues from there (:mod:`dcmviz.sweep.search`).  Unlike :meth:`restore_state`, which
        refuses a state from another backend, the backend here is built for the state."""
        session = cls(state.config, backend=state.backend_name)
        session._restore(state)
        return session

    def restore_state(self, state: SessionState) -> None:
        """Continue from ``state`` (saved by this session with the same backend): the next
        :meth:`step` is the one that followed it.  The recorded history restarts there."""
        if state.owner != id(self.backend):
            raise ValueError(
                "state: saved with another backend (the robot, terrain or backend changed "
                "since); it restores only into the backend it came from"
            )
        self._restore(state)

    def _restore(self, state: SessionState) -> None:
        self.last_state = self.backend.set_state(state.backend)
        self.config = state.config
        self.walker = state.walker.copy()
        self.last_command = state.last_command
        self.pushes = list(state.pushes)
        self._pending = list(state.pending)
        self._applied = {b: f.copy() for b, f in state.applied.items()}
        self.metrics = copy.copy(state.metrics)
        self._ticks = state.ticks
        self._tick = None
        self._history = {
            k: np.full((HISTORY,) if k == "t" else (HISTORY, 3), np.nan) for k in HISTORY_KEYS
        }
        self._n = 0
        self._records_seen, self._records_recent = None, ()
        self.release()

    def replay(self, forces: Iterable[Mapping[str, np.ndarray]]) -> None:
        """Step once per entry of ``forces``, applying those external forces (body → N) instead
        of the push schedule and any pull: a recorded run again, tick for tick.  Subscribers
        are not told (the ticks were told when they first happened)."""
        for given in forces:
            self._step(given, notify=False)

    # -- summaries ------------------------------------------------------------------------------
    @property
    def steps_completed(self) -> int:
        return self.walker.status.steps_completed

    @property
    def step_adjustments(self) -> list[dict[str, float]]:
        return self.walker.step_adjustments

    def realised_steps(self) -> list:
        """The footsteps landed since the reset (:class:`~dcmviz.gait.walk.StepRecord`; a
        continuous walk keeps its last ``gait.walk.RECORDS_KEPT``)."""
        return list(self.walker.status.records)
