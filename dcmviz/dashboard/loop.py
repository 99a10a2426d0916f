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
from dcmviz.dashboard.timeline import Timeline
from dcmviz.gait import GaitPlan
from dcmviz.robots import Robot
from dcmviz.robots.heap import release_freed_memory
from dcmviz.robots.pose import RobotPose
from dcmviz.session import Session, Tick

FALL_PAUSE_S = 1.0  # wall seconds the fallen robot stays visible before the reset
PLAN_END_PAUSE_S = 1.5  # sim seconds standing at the end of a plan before looping
MAX_LAG_S = 1.0  # sim seconds the loop may fall behind (e.g. descheduled) and still catch up
SNAPSHOT_DT = 1.0 / 60.0  # wall seconds between published snapshots
PLOT_WINDOW_S = 8.0  # sim seconds of signals in a snapshot's plot window (the default)
HISTORY_DT = 0.2  # wall seconds between plot windows while the walk runs (the live plot rate)
HOLD_MAX_S = 10.0  # wall seconds a newcomer's tab may hold the walk at its start while it loads
CONFIG_MIN_INTERVAL_S = 0.2  # configs are adopted at most this often (a dragged slider: the
# newest waits; a restart per slider event, 30 a second, would stop the simulation keeping up)
FALLS_BEFORE_PAUSE = 2  # falls in a row with one setting and no push: the walk pauses
PUSH_BLAME_S = 2.5  # a fall within this long (sim s) after a push began is the push's
STEP_FOOTSTEP_MAX_S = 3.0  # stepping to the next footstep simulates at most this long


@dataclass(frozen=True)
class Fall:
    """What the loop knows of a fall: when, the push just before it, how many in a row."""

    t: float  # s, walk time of the fall
    push: tuple[float, str, np.ndarray, bool] | None  # a recent push: (start s, body, peak
    # force N, whether a drag pulled)
    streak: int  # falls in a row with this config version and no push (this one included)
    paused: bool  # the walk pauses after the reset (FALLS_BEFORE_PAUSE reached)


@dataclass(frozen=True)
class LoopStatus:
    """What the simulation loop adds to the session's tick: its clock, play state and counters."""

    t: float = 0.0  # s, simulation time of the frame shown
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
    frame: int | None = None  # the buffered frame shown (None: the live end)
    frame_back_s: float = 0.0  # s, how far that frame lies before the newest one
    buffer_s: float = 0.0  # s of ticks buffered
    buffer_bytes: int = 0  # memory of the buffer
    paused_reason: str = ""  # why the loop paused itself ('' when running or paused by a user)
    resumes: int = 0  # "resume from here" commands handled
    pulling: bool = False  # a spring pull is on
    plot_window_s: float = PLOT_WINDOW_S


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
    def nominal_plan(self) -> GaitPlan | None:
        """The plan as the settings made it, before step adjustment moved any footstep."""
        if self.tick is not None:
            return self.tick.nominal_plan
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
    """Runs ``session.step()`` paced to real time × speed in a daemon thread, keeps every tick
    in its :class:`~dcmviz.dashboard.timeline.Timeline` and shows the live end or a buffered
    frame."""

    def __init__(
        self,
        session_factory: Callable[[Config], Session],
        config: Config,
        *,
        on_event: Callable[[str, str], None] | None = None,
        loop_plan: bool = True,
        timeline: Timeline | None = None,
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
        self.resumes = 0
        self.version = 0
        self.note = ""  # what the last config change did ("gains changed (walk continues)", …)
        self.note_seq = 0  # incremented with every note
        self.timeline = timeline if timeline is not None else Timeline()
        self.cursor: int | None = None  # the buffered frame shown (None: the live end)
        self.plot_window_s = PLOT_WINDOW_S
        self.pause_after_push_s = 0.0  # > 0: pause this long (sim s) after each push starts
        self.paused_reason = ""
        self.last_fall: Fall | None = None
        self._fall_streak = (-1, 0)  # (config version, falls in a row without a push)
        self._pause_after_reset = False
        self._pause_at: float | None = None  # sim time to pause at (after a push)
        self.snapshot = Snapshot()
        self._commands: queue.Queue[tuple[str, Any]] = queue.Queue()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._rtf_window: deque[tuple[float, float]] = deque(maxlen=120)
        self._step_times: deque[float] = deque(maxlen=200)
        self._fallen_at: float | None = None
        self._last_history = 0.0
        self._recorded: Tick | None = None  # the last tick put into the timeline
        self._playback_wall = 0.0
        self._pending_config: Any = None  # (version, Config) waiting for CONFIG_MIN_INTERVAL_S
        self._config_at = -float("inf")  # perf_counter of the last adopted config
        self._hold_until = 0.0  # perf_counter until which the clock stands still ("hold")
        self._publish()

    # -- commands (any thread) --------------------------------------------------------------------
    def post(self, kind: str, payload: Any = None) -> None:
        """Queue a command: config, reset, push, pull, release, play, speed, loop, hold, seek,
        step, live, resume, plot_window, pause_after_push or call."""
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
        by hand (no thread started: ``session.step()`` by the caller), e.g. headless use; the
        session's last tick is buffered first."""
        self._record()
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
                    self.cursor = None
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
                self._playback_wall = time.perf_counter()
            now = time.perf_counter()
            if self._fallen_at is not None:
                if now - self._fallen_at >= FALL_PAUSE_S:
                    self._fallen_at = None
                    self._reset_walk()
                    if self._pause_after_reset:
                        self._pause_after_reset = False
                        self.playing = False
                    wall0, sim0 = time.perf_counter(), self.session.t
                    self._publish()
                time.sleep(0.02)
                continue
            if self.playing and self.cursor is not None and not self.held:
                self._play_back(now)  # through the buffer towards the live end
                wall0, sim0 = time.perf_counter(), self.session.t
                if now - last_publish >= SNAPSHOT_DT:
                    self._publish()
                    last_publish = now
                time.sleep(0.005)
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
                if not self._step_once():
                    break
                if not self.playing:  # paused itself (after a push)
                    break
            if self.session.t < target - MAX_LAG_S:  # cannot keep up: stop trying to catch up
                wall0, sim0 = time.perf_counter(), self.session.t
            if self._maybe_loop_plan():
                wall0, sim0 = time.perf_counter(), self.session.t
            now = time.perf_counter()
            self._rtf_window.append((now, self.session.t))
            if now - last_publish >= SNAPSHOT_DT or self._fallen_at is not None or not self.playing:
                self._publish()
                last_publish = now
            ahead = (self.session.t - target) / max(self.speed, 1e-3)
            time.sleep(min(max(ahead, 0.0), 0.01) if ahead > 0 else 0.0005)

    def _step_once(self) -> bool:
        """One control tick, buffered; False when the walk stopped (a fault or a fall)."""
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
            self._reset_walk()
            return False
        self._step_times.append(time.perf_counter() - t_step)
        self._record()
        if getattr(self.session, "fell", False):
            self._on_fall()
            return False
        if self._pause_at is not None and self.session.t >= self._pause_at - 1e-9:
            self._pause_at = None
            self.playing = False
            self.paused_reason = "paused after the push (Simulate → Time: step back through it)"
        return True

    def _record(self) -> None:
        """Put the session's last tick into the timeline (and a checkpoint when due)."""
        tick = self.session.tick()
        if tick is None or tick is self._recorded:
            return
        self._recorded = tick
        self.timeline.append(tick)
        if self.timeline.wants_checkpoint(tick):
            self.timeline.checkpoint(self.session.save_state(), tick.t)

    def _on_fall(self) -> None:
        self.falls += 1
        self._fallen_at = time.perf_counter()
        last = self.timeline.last_seq
        push = self.timeline.recent_push(last, PUSH_BLAME_S) if last is not None else None
        version, streak = self._fall_streak
        streak = 0 if push is not None else (streak + 1 if version == self.version else 1)
        self._fall_streak = (self.version, streak)
        paused = streak >= FALLS_BEFORE_PAUSE
        self._pause_after_reset = paused
        self.last_fall = Fall(float(self.session.t), push, streak, paused)
        if paused:
            self.paused_reason = f"paused after {streak} falls in a row with these settings"
        self.on_event("fell", f"The robot fell at t = {self.session.t:.2f} s; resetting.")

    def _reset_walk(self) -> None:
        """The walk from its start (the buffer keeps the walk before: a new walk in it)."""
        self.session.reset()
        self._rtf_window.clear()
        self._pause_at = None

    def _maybe_loop_plan(self) -> bool:
        session = self.session
        if not self.loop_plan or session.config.gait.mode != "plan":
            return False
        if session.t > session.plan.t_end + PLAN_END_PAUSE_S:
            self._reset_walk()
            return True
        return False

    def _play_back(self, now: float) -> None:
        """Move the shown frame on by the wall time since the last call × speed."""
        dt = self.timeline.dt or 1e-3
        frames = int((now - self._playback_wall) * self.speed / dt)
        if frames <= 0:
            return
        self._playback_wall += frames * dt / self.speed
        last = self.timeline.last_seq
        if last is None or self.cursor + frames >= last:
            self.cursor = None  # the live end: the simulation goes on from here
        else:
            self.cursor += frames

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
            self.timeline.mark_dirty()
        elif kind == "reset":
            self._fallen_at = None
            self._pause_after_reset = False
            self.cursor = None
            self._reset_walk()
            self.resets += 1
        elif kind == "push":
            self.session.push(**payload)
            self.timeline.mark_dirty()
            if self.pause_after_push_s > 0:
                self._pause_at = self.session.t + self.pause_after_push_s
        elif kind == "pull":
            self.session.pull(**payload)
        elif kind == "release":
            self.session.release()
        elif kind == "play":
            self.playing = bool(payload)
            self.paused_reason = ""
            if self.playing and self.cursor is None:
                self._fall_streak = (self.version, 0)
        elif kind == "speed":
            self.speed = float(payload)
        elif kind == "loop":
            self.loop_plan = bool(payload)
        elif kind == "hold":  # seconds to stand still (at most HOLD_MAX_S); 0 releases
            self._hold_until = time.perf_counter() + min(max(float(payload), 0.0), HOLD_MAX_S)
        elif kind == "seek":  # seconds before the newest frame (0: the newest)
            self.playing = False
            seq = self.timeline.seq_back(float(payload))
            self.cursor = None if seq is None or seq == self.timeline.last_seq else seq
        elif kind == "step":  # ("tick" | "footstep", +1 | -1)
            self.playing = False
            self._step_command(*payload)
        elif kind == "live":
            self.cursor = None
        elif kind == "resume":
            self._resume()
        elif kind == "plot_window":
            self.plot_window_s = min(max(float(payload), 0.5), self.timeline.seconds)
        elif kind == "pause_after_push":
            self.pause_after_push_s = max(float(payload), 0.0)
        elif kind == "call":
            payload(self.session)
        else:
            raise ValueError(f"unknown command {kind!r}")

    def _step_command(self, unit: str, direction: int) -> None:
        """One tick or one footstep back or forward: through the buffer, or simulated at the
        live end (one control tick; until the next touchdown, at most STEP_FOOTSTEP_MAX_S)."""
        tl = self.timeline
        last = tl.last_seq
        if direction < 0:
            here = self.cursor if self.cursor is not None else last
            if here is None:
                return
            if unit == "tick":
                self.cursor = max(here - 1, tl.first_seq)
            else:
                found = tl.footstep(here, -1)
                self.cursor = found if found is not None else here
            return
        if self.cursor is not None:
            nxt = self.cursor + 1 if unit == "tick" else tl.footstep(self.cursor, +1)
            self.cursor = None if nxt is None or nxt >= last else nxt
            return
        if self._fallen_at is not None:
            return
        if unit == "tick":
            self._step_once()
            return
        steps, t_end = self.session.steps_completed, self.session.t + STEP_FOOTSTEP_MAX_S
        while self.session.steps_completed == steps and self.session.t < t_end:
            if not self._step_once():
                break

    def _resume(self) -> None:
        """Restart the physics from the frame shown, exactly as it was there (the last checkpoint
        before it, then its ticks replayed with the forces they had), with the gains set now;
        the buffered frames after it are dropped and the walk plays on from there."""
        tl = self.timeline
        seq = self.cursor if self.cursor is not None else tl.last_seq
        if seq is None:
            return
        current = self.session.config
        state, forces, seq = tl.resume_from(seq)
        shown_t = tl.time_of(seq)  # the time the scrubbed frame showed (its tick's start)
        session = self.session
        session.restore_state(state)
        session.replay(forces)
        walked = session.config
        exact = True
        stored = tl.physics(seq)
        tick = session.tick()
        if stored is not None and tick is not None and tick.physics is not None:
            exact = bool(np.array_equal(tick.physics, stored))
        if current.control != walked.control:
            session.set_config(walked.model_copy(update={"control": current.control}))
        tl.truncate_after(seq)
        self._recorded = session.tick()
        tl.checkpoint(session.save_state(), float(session.t))
        self.cursor = None
        self._fallen_at = None
        self._pause_at = None
        self.playing = True
        self.paused_reason = ""
        self._rtf_window.clear()
        self.resumes += 1
        edits = [k for k in ("robot", "gait", "dcm", "sim", "pushes", "terrain")
                 if getattr(current, k) != getattr(walked, k)]  # fmt: skip
        # the frame's own time, as the time bar showed it: the session's clock stands one tick
        # later (the frame's end), and at a 5 ms tick t.xx5 rounds either way
        self.note = f"resumed from t = {shown_t:.2f} s" + ("" if exact else " (not exact)")
        if edits:
            self.note += f"; the walk's own {', '.join(edits)} settings"
        self.note_seq += 1
        self.on_event("resumed", self.note)

    def _apply_config(self, config: Config) -> None:
        """Gains act on the running walk; anything else restarts it (``note`` says which)."""
        change = self.session.set_config(config, backend=config.sim.backend)
        if change.startswith("restarted") or change == "started":
            self._fallen_at = None
            self._pause_at = None
            self.cursor = None
            self._rtf_window.clear()
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
        return max(0.0, (w[-1][1] - w[0][1]) / (w[-1][0] - w[0][0]))

    def _publish(self) -> None:
        """A new snapshot: the session's last :class:`~dcmviz.session.tick.Tick` (nothing else
        of the session's) or a buffered frame's, and the loop's status."""
        s = self.session
        tl = self.timeline
        cursor = self.cursor
        now = time.perf_counter()
        if cursor is not None:
            try:
                tick = tl.tick(cursor)
            except IndexError:  # fell out of the buffer
                self.cursor = cursor = None
        if cursor is None:
            tick = s.tick()
        last = tl.last_seq
        history = self.snapshot.history
        shown = cursor if cursor is not None else last
        if shown is not None and (
            cursor is not None or now - self._last_history >= HISTORY_DT or not self.playing
        ):
            try:
                history = tl.window(shown, self.plot_window_s)
            except IndexError:
                history = {}
            self._last_history = now
        elif shown is None:
            history = {}
        back = 0.0 if cursor is None or last is None else (last - cursor) * tl.dt
        status = LoopStatus(
            t=float(tick.t) if cursor is not None else float(s.t),
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
            frame=cursor,
            frame_back_s=back,
            buffer_s=tl.seconds_kept(),
            buffer_bytes=tl.nbytes,
            paused_reason=self.paused_reason if not self.playing or self._fallen_at else "",
            resumes=self.resumes,
            pulling=s.tick() is not None and s.tick().pull is not None,
            plot_window_s=self.plot_window_s,
        )
        rest = None
        if tick is None:  # reset, not stepped yet: the walk's plan, standing
            rest = Rest(s.plan, s.plan_version, np.array(s.last_state.com, float),
                        s.backend.robot_pose())  # fmt: skip
        self.snapshot = Snapshot(tick=tick, status=status, rest=rest, history=history)
