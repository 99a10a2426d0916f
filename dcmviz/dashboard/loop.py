"""The simulation in a background thread: it owns the session and its clock.

The dashboard never touches the session directly: it posts commands (new config, reset, push,
play/pause, speed) and reads the latest immutable :class:`Snapshot` (mjviser's inversion of
control: the loop owns time, the view reads snapshots).
"""

from __future__ import annotations

import queue
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dcmviz.config import Config
from dcmviz.gait import GaitPlan
from dcmviz.robots import Robot
from dcmviz.robots.heap import release_freed_memory
from dcmviz.robots.pose import RobotPose
from dcmviz.session import Session, Tick

FALL_PAUSE_S = 1.0  # wall seconds the fallen robot stays visible before the reset
PLAN_END_PAUSE_S = 1.5  # sim seconds standing at the end of a plan before looping
MAX_LAG_S = 1.0  # sim seconds the loop may fall behind (e.g. descheduled) and still catch up
SNAPSHOT_DT = 1.0 / 60.0  # wall seconds between published snapshots
HISTORY_WINDOW_S = 8.0  # sim seconds of history in a snapshot
HISTORY_DT = 0.2  # wall seconds between history copies (the live plot rate)
HOLD_MAX_S = 10.0  # wall seconds a newcomer's tab may hold the walk at its start while it loads
CONFIG_MIN_INTERVAL_S = 0.2  # configs are adopted at most this often (a dragged slider: the
# newest waits; a restart per slider event, 30 a second, would stop the simulation keeping up)


@dataclass(frozen=True)
class LoopStatus:
    """What the simulation loop adds to the session's tick: its clock, play state and counters."""

    t: float = 0.0  # s, simulation time
    backend: str = ""
    robot: Robot | None = None  # the robot walked
    playing: bool = False
    speed: float = 1.0
    real_time_factor: float = 0.0
    falls: int = 0
    fallen: bool = False  # the robot lies fallen (the walk resets in FALL_PAUSE_S)
    version: int = 0  # config version this snapshot was simulated with
    note: str = ""  # what the last config change did, for the status line
    note_seq: int = 0  # counts config changes that set a note (a repeated note is a new one)
    step_time_s: float = 0.0  # mean wall time of one control tick
    resets: int = 0  # reset commands handled before this snapshot
    held: bool = False  # the walk waits at its start for a newcomer's tab to finish loading


@dataclass(frozen=True)
class Rest:
    """A walk just reset, before its first tick: the plan and where the robot stands."""

    plan: GaitPlan
    plan_version: int
    com: np.ndarray
    pose: RobotPose | None  # the humanoid standing (None for the point mass)


@dataclass(frozen=True)
class Snapshot:
    """What the view draws: the session's last tick (or, right after a reset, the walk at rest)
    and the loop's status; the live plot's history window."""

    tick: Tick | None = None  # the session's record of the last tick (None right after a reset)
    status: LoopStatus = LoopStatus()
    rest: Rest | None = None  # the walk at rest when there is no tick yet
    history: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def plan(self) -> GaitPlan | None:
        """The plan the walker walks (continuous: the receding horizon)."""
        if self.tick is not None:
            return self.tick.plan
        return None if self.rest is None else self.rest.plan

    @property
    def plan_version(self) -> int:
        """Changes whenever the walked plan does."""
        if self.tick is not None:
            return self.tick.plan_version
        return 0 if self.rest is None else self.rest.plan_version

    @property
    def com(self) -> np.ndarray | None:
        """The measured CoM (m)."""
        if self.tick is not None:
            return self.tick.state.com
        return None if self.rest is None else self.rest.com

    @property
    def pose(self) -> RobotPose | None:
        """The humanoid's links (None for the point mass)."""
        if self.tick is not None:
            return self.tick.pose
        return None if self.rest is None else self.rest.pose


def _finite(*arrays: Any) -> bool:
    """Every value of the given arrays is finite (None counts as finite)."""
    return all(a is None or bool(np.isfinite(a).all()) for a in arrays)


class SimLoop:
    """Runs ``session.step()`` paced to real time × speed in a daemon thread."""

    def __init__(
        self,
        session_factory: Callable[[Config], Session],
        config: Config,
        *,
        on_event: Callable[[str, str], None] | None = None,
        loop_plan: bool = True,
    ) -> None:
        self._factory = session_factory
        self.session = session_factory(config)
        self.on_event = on_event or (lambda kind, message: None)
        self.loop_plan = loop_plan
        self.playing = True
        self.speed = 1.0
        self.falls = 0
        self.faults = 0  # ticks that raised or left a non-finite state (each resets the walk)
        self.resets = 0  # reset commands handled (tests and the status line watch it)
        self.version = 0
        self.note = ""  # what the last config change did ("gains changed (walk continues)", …)
        self.note_seq = 0  # incremented with every note
        self.snapshot = Snapshot()
        self._commands: queue.Queue[tuple[str, Any]] = queue.Queue()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._rtf_window: deque[tuple[float, float]] = deque(maxlen=120)
        self._step_times: deque[float] = deque(maxlen=200)
        self._fallen_at: float | None = None
        self._last_history = 0.0
        self._pending_config: Any = None  # (version, Config) waiting for CONFIG_MIN_INTERVAL_S
        self._config_at = -float("inf")  # perf_counter of the last adopted config
        self._hold_until = 0.0  # perf_counter until which the clock stands still ("hold")
        self._publish()

    # -- commands (any thread) --------------------------------------------------------------------
    def post(self, kind: str, payload: Any = None) -> None:
        """Queue a command: config, reset, push, play, speed, loop, hold or call."""
        self._commands.put((kind, payload))

    def call(self, fn: Callable[[Session], Any], timeout: float = 10.0) -> Any:
        """Run ``fn(session)`` on the simulation thread (or here if it is not running)."""
        if self._thread is None or not self._thread.is_alive():
            return fn(self.session)
        done = threading.Event()
        box: dict[str, Any] = {}

        def run(session: Session) -> None:
            try:
                box["value"] = fn(session)
            except Exception as err:  # noqa: BLE001 - handed back to the caller
                box["error"] = err
            done.set()

        self.post("call", run)
        if not done.wait(timeout):
            raise TimeoutError("the simulation thread did not answer")
        if "error" in box:
            raise box["error"]
        return box.get("value")

    def pump(self) -> Snapshot:
        """Apply the queued commands and publish a snapshot now; returns it.  For a loop driven
        by hand (no thread started: ``session.step()`` by the caller), e.g. headless use."""
        self._handle_commands()
        self._publish()
        return self.snapshot

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="dcmviz-sim", daemon=True)
        self._thread.start()

    def running(self) -> bool:
        """The simulation thread runs (it was started and has not stopped)."""
        return self._thread is not None and self._thread.is_alive()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)

    # -- the thread -------------------------------------------------------------------------------
    def _run(self) -> None:
        """The thread: a fault that escapes the loop (even a reset that raises) rebuilds the
        session from the last configuration instead of ending the simulation."""
        while not self._stop.is_set():
            try:
                self._loop()
            except Exception as err:  # noqa: BLE001 - the simulation must outlive any fault
                self.on_event("error", f"Simulation fault ({err!r}); the session restarts.")
                try:
                    self.session = self._factory(self.session.config)
                    self._fallen_at = None
                    self._publish()
                except Exception as again:  # noqa: BLE001
                    self.on_event("error", f"The session could not restart: {again!r}")
                    self._stop.wait(1.0)

    def _loop(self) -> None:
        wall0, sim0 = time.perf_counter(), self.session.t
        last_publish = 0.0
        while not self._stop.is_set():
            if self._handle_commands():
                wall0, sim0 = time.perf_counter(), self.session.t
                self._rtf_window.clear()
            now = time.perf_counter()
            if self._fallen_at is not None:
                if now - self._fallen_at >= FALL_PAUSE_S:
                    self._fallen_at = None
                    self.session.reset()
                    wall0, sim0 = time.perf_counter(), self.session.t
                    self._publish()
                time.sleep(0.02)
                continue
            if not self.playing or self.held:
                if now - last_publish > 0.1:
                    self._publish()
                    last_publish = now
                time.sleep(0.02)
                wall0, sim0 = time.perf_counter(), self.session.t
                continue
            target = sim0 + self.speed * (now - wall0)
            frame_end = now + SNAPSHOT_DT
            while self.session.t < target and time.perf_counter() < frame_end:
                t_step = time.perf_counter()
                try:
                    command = self.session.step()
                    if not _finite(command.v_cmd, command.xi, self.session.last_state.com):
                        raise FloatingPointError("the state is not finite (NaN or inf)")
                except Exception as err:  # noqa: BLE001 - a crash in physics must not kill the UI
                    self.faults += 1
                    self.on_event(
                        "error",
                        f"Simulation fault at t = {self.session.t:.2f} s ({err}); the walk restarts.",
                    )
                    self.session.reset()
                    break
                self._step_times.append(time.perf_counter() - t_step)
                if getattr(self.session, "fell", False):
                    self.falls += 1
                    self._fallen_at = time.perf_counter()
                    self.on_event(
                        "fell", f"The robot fell at t = {self.session.t:.2f} s; resetting."
                    )
                    break
            if self.session.t < target - MAX_LAG_S:  # cannot keep up: stop trying to catch up
                wall0, sim0 = time.perf_counter(), self.session.t
            self._maybe_loop_plan()
            now = time.perf_counter()
            self._rtf_window.append((now, self.session.t))
            if now - last_publish >= SNAPSHOT_DT or self._fallen_at is not None:
                self._publish()
                last_publish = now
            ahead = (self.session.t - target) / max(self.speed, 1e-3)
            time.sleep(min(max(ahead, 0.0), 0.01) if ahead > 0 else 0.0005)

    def _maybe_loop_plan(self) -> None:
        session = self.session
        if not self.loop_plan or session.config.gait.mode != "plan":
            return
        plan = session.plan
        if session.t > plan.t_end + PLAN_END_PAUSE_S:
            session.reset()
            self._rtf_window.clear()

    def _handle_commands(self) -> bool:
        """Apply queued commands; True when the clock must be re-anchored.

        Of several queued configs (a slider being dragged) only the newest is applied, and
        the running loop adopts configs at most every CONFIG_MIN_INTERVAL_S: a newer one waits
        (replacing any waiting one) and is adopted when the interval has passed.
        """
        commands: list[tuple[str, Any]] = []
        while True:
            try:
                commands.append(self._commands.get_nowait())
            except queue.Empty:
                break
        last_config = max((i for i, (k, _) in enumerate(commands) if k == "config"), default=-1)
        if last_config >= 0:
            self._pending_config = commands[last_config][1]
        paced = self._thread is not None and self._thread.is_alive()  # (not when driven by hand)
        due = self._pending_config is not None and (
            not paced or time.perf_counter() - self._config_at >= CONFIG_MIN_INTERVAL_S
        )
        if not commands and not due:
            return False
        applied = False
        for i, (kind, payload) in enumerate(commands):
            if kind == "config":
                if i == last_config and due:  # in its place among the other commands
                    applied = self._adopt_pending() or applied
                continue
            self._run_command(kind, payload)
            applied = True
        if due and self._pending_config is not None:  # waiting from an earlier batch
            applied = self._adopt_pending() or applied
        if applied:
            self._publish()
        return applied

    def _adopt_pending(self) -> bool:
        payload, self._pending_config = self._pending_config, None
        self._config_at = time.perf_counter()
        self._run_command("config", payload)
        return True

    def _run_command(self, kind: str, payload: Any) -> None:
        try:
            self._apply(kind, payload)
        except Exception as err:  # noqa: BLE001 - a bad command must not stop the simulation
            self.on_event("error", f"{kind}: {err}")

    def _apply(self, kind: str, payload: Any) -> None:
        if kind == "config":
            version, config = payload
            self._apply_config(config)
            self.version = version
        elif kind == "reset":
            self._fallen_at = None
            self.session.reset()
            self.resets += 1
        elif kind == "push":
            self.session.push(**payload)
        elif kind == "play":
            self.playing = bool(payload)
        elif kind == "speed":
            self.speed = float(payload)
        elif kind == "loop":
            self.loop_plan = bool(payload)
        elif kind == "hold":  # seconds to stand still (at most HOLD_MAX_S); 0 releases
            self._hold_until = time.perf_counter() + min(max(float(payload), 0.0), HOLD_MAX_S)
        elif kind == "call":
            payload(self.session)
        else:
            raise ValueError(f"unknown command {kind!r}")

    def _apply_config(self, config: Config) -> None:
        """Gains act on the running walk; anything else restarts it (``note`` says which)."""
        change = self.session.set_config(config, backend=config.sim.backend)
        if change.startswith("restarted") or change == "started":
            self._fallen_at = None
            release_freed_memory()  # the replaced simulation's models and data
        if change:
            self.note = change
            self.note_seq += 1

    @property
    def held(self) -> bool:
        """The clock stands still for a newcomer's tab (see the "hold" command)."""
        return time.perf_counter() < self._hold_until

    # -- snapshots --------------------------------------------------------------------------------
    def real_time_factor(self) -> float:
        w = self._rtf_window
        if len(w) < 2 or w[-1][0] - w[0][0] < 1e-3:
            return 0.0
        return (w[-1][1] - w[0][1]) / (w[-1][0] - w[0][0])

    def _publish(self) -> None:
        """A new snapshot: the session's last :class:`~dcmviz.session.tick.Tick` (nothing else
        of the session's) and the loop's status."""
        s = self.session
        tick = s.tick()
        now = time.perf_counter()
        history = self.snapshot.history
        if now - self._last_history >= HISTORY_DT or not self.playing:
            history = self._history_window(s)
            self._last_history = now
        status = LoopStatus(
            t=float(s.t),
            backend=s.backend_name,
            robot=s.robot,
            playing=self.playing,
            speed=self.speed,
            real_time_factor=self.real_time_factor(),
            falls=self.falls,
            fallen=self._fallen_at is not None,
            version=self.version,
            note=self.note,
            note_seq=self.note_seq,
            step_time_s=float(np.mean(self._step_times)) if self._step_times else 0.0,
            resets=self.resets,
            held=self.held,
        )
        rest = None
        if tick is None:  # reset, not stepped yet: the walk's plan, standing
            rest = Rest(s.plan, s.plan_version, np.array(s.last_state.com, float),
                        s.backend.robot_pose())  # fmt: skip
        self.snapshot = Snapshot(tick=tick, status=status, rest=rest, history=history)

    @staticmethod
    def _history_window(session: Session) -> dict[str, np.ndarray]:
        hist = session.history()
        t = np.asarray(hist["t"])
        if len(t) == 0:
            return {}
        keep = t >= t[-1] - HISTORY_WINDOW_S
        stride = max(1, int(keep.sum()) // 600)
        return {k: np.array(np.asarray(v)[keep][::stride]) for k, v in hist.items()}
