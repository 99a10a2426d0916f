"""The time buffer: the last BUFFER_S seconds of ticks, to pause, step, scrub and resume from.

Every control tick the simulation loop appends the session's :class:`~dcmviz.session.Tick` to a
:class:`Timeline`: its numbers go into fixed-size ring columns (float32 for what is drawn and
plotted, float64 for the external forces and the backend's physical state, e.g. MuJoCo's
mjSTATE_FULLPHYSICS), its shared objects (the robot, the walked and nominal plans, the landed
footsteps, which change only at touchdowns, and the swing foot's path, which changes at lift-off
and when the recovery moves its footstep) by reference.  :meth:`Timeline.tick` rebuilds the
tick of any buffered frame for drawing (its numbers as float32 copies), :meth:`Timeline.window`
gives the plotted signals around a frame.

Resuming from a frame is exact: every CHECKPOINT_S (and at each walk's first tick, and after any
command that changes the walk: a push, new gains) the loop stores a
:class:`~dcmviz.session.SessionState`; :meth:`Timeline.resume_from` hands back the last
checkpoint at or before the frame and the external forces each tick after it received, which
the session replays (:meth:`~dcmviz.session.Session.replay`) to reach the frame's state bit for
bit (the loop compares the frame's physical state to make sure).

Frames are numbered by ``seq``, counting every tick appended since the timeline was made (across
resets: a reset starts a new *walk* within the buffer, with its own times).  The memory is
bounded by the capacity, fixed when the first tick of a robot arrives: ``nbytes``.
"""

from __future__ import annotations

import bisect
import math
import threading
from dataclasses import dataclass

import numpy as np

from dcmviz.robots import Robot
from dcmviz.robots.feet import SIDES
from dcmviz.robots.pose import RobotPose
from dcmviz.session import AppliedPush, Pull, SessionState, Tick
from dcmviz.walker.state import FootTarget, MeasuredState, WalkerCommand

BUFFER_S = 60.0  # sim seconds of ticks kept
CHECKPOINT_S = 0.1  # sim seconds between checkpoints (resuming replays at most this much)
PUSH_SLOTS = 3  # external forces on at most this many bodies at once are kept per tick
CONTACT_SLOTS = 2
SIGNALS_3D = ("xi", "xi_ref", "xi_adj", "v_ref", "v_cmd", "com", "f_hat", "f_ext", "cop")

# integer columns
(I_INDEX, I_WALK, I_PLAN_VERSION, I_ADJ, I_REC, I_STEPS, I_NEXT, I_PHASE, I_STEP_INDEX,
 I_FLAGS, I_SWING, I_CONTACTS, I_PULL) = range(13)  # fmt: skip
PUSH0 = 13  # then the pushed bodies (index into robot.spec.bodies, -1 none)
N_INT = PUSH0 + PUSH_SLOTS
F_FELL, F_DONE, F_CMD_DONE, F_SUP_L, F_SUP_R, F_CON_L, F_CON_R, F_PULL, F_MOMENT = (
    1 << k for k in range(9)
)


@dataclass(frozen=True)
class Layout:
    """Where each quantity sits in a float32 row (slices), for one robot."""

    joints: tuple[str, ...]
    slices: dict[str, slice]
    width: int

    @staticmethod
    def of(joints: tuple[str, ...]) -> Layout:
        sizes = [
            ("t", 1), ("dt", 1), ("com", 3), ("com_velocity", 3), ("feet", 6), ("feet_yaw", 2),
            ("applied", 3), ("moment", 3),
            ("target_p", 6), ("target_v", 6), ("target_a", 6), ("target_yaw", 2),
            ("target_yaw_rate", 2), ("com_force", 3), ("contact_force", 3),
            ("xi", 3), ("xi_ref", 3), ("xi_adj", 3), ("v_ref", 3), ("v_cmd", 3), ("f_hat", 3),
            ("v_cmd_rate", 3), ("base", 3), ("wxyz", 4), ("joints", len(joints)),
            ("adjusted", 3), ("recovery", 3), ("contacts", 6 * CONTACT_SLOTS), ("cop", 3),
            ("pull", 8), ("push_points", 3 * PUSH_SLOTS), ("mass", 1),
        ]  # fmt: skip
        slices, at = {}, 0
        for name, n in sizes:
            slices[name] = slice(at, at + n)
            at += n
        return Layout(tuple(joints), slices, at)


_NAN3 = np.full(3, np.nan)
_ZERO3 = np.zeros(3)
_ZERO8 = np.zeros(8)


def _capacity(dt: float, seconds: float) -> int:
    return int(math.ceil(seconds / dt)) + 1


class Timeline:
    """A ring of the last ``seconds`` of ticks and the checkpoints to resume from them.

    Thread-safe: the simulation thread appends, other threads read rebuilt ticks and windows.
    """

    def __init__(self, seconds: float = BUFFER_S, checkpoint_s: float = CHECKPOINT_S) -> None:
        self.seconds = float(seconds)
        self.checkpoint_s = float(checkpoint_s)
        self._lock = threading.RLock()
        self.robot: Robot | None = None
        self.backend = ""
        self.dt = 0.0
        self.capacity = 0
        self.layout: Layout | None = None
        self.next_seq = 0  # seq of the next frame appended
        self.first_seq = 0  # oldest frame kept
        self._walk = 0
        self._last_index = -1
        self._checkpoints: dict[int, SessionState] = {}
        self._checkpoint_seqs: list[int] = []
        self._last_checkpoint_t = -math.inf
        self._dirty = False
        self._bodies: tuple[str, ...] = ()

    # -- size -------------------------------------------------------------------------------
    def __len__(self) -> int:
        return self.next_seq - self.first_seq

    @property
    def last_seq(self) -> int | None:
        return self.next_seq - 1 if len(self) else None

    @property
    def nbytes(self) -> int:
        """Bytes of the ring columns (allocated once per robot) and the checkpoints held."""
        if self.layout is None:
            return 0
        columns = self._f32.nbytes + self._ints.nbytes + self._forces.nbytes + self._phys.nbytes
        columns += 8 * 3 * self.capacity  # the object columns' references
        return columns + CHECKPOINT_BYTES * len(self._checkpoint_seqs)

    def seconds_kept(self) -> float:
        return len(self) * self.dt

    # -- writing (the simulation thread) -------------------------------------------------------
    def clear(self) -> None:
        with self._lock:
            self.first_seq = self.next_seq
            self._checkpoints.clear()
            self._checkpoint_seqs.clear()
            self._last_checkpoint_t = -math.inf
            self._last_index = -1

    def _allocate(self, tick: Tick) -> None:
        robot = tick.robot
        self.robot, self.backend = robot, tick.backend
        self.dt = float(tick.state.t - tick.t) or 1e-3
        self.capacity = _capacity(self.dt, self.seconds)
        joints = tuple(tick.pose.joints) if tick.pose is not None else ()
        self.layout = Layout.of(joints)
        self._bodies = tuple(robot.spec.bodies)
        n = self.capacity
        self._f32 = np.zeros((n, self.layout.width), np.float32)
        self._ints = np.zeros((n, N_INT), np.int32)
        self._forces = np.zeros((n, PUSH_SLOTS, 3))
        n_phys = 0 if tick.physics is None else len(tick.physics)
        self._phys = np.zeros((n, n_phys))
        self._robots: list = [None] * n
        # (plan, nominal_plan, realised_steps, swing path as float32: one array per swing path,
        # shared by the frames that drew it)
        self._plans: list = [None] * n
        self._path_source: np.ndarray | None = None
        self._path: np.ndarray | None = None
        self.clear()

    def append(self, tick: Tick) -> int:
        """Keep ``tick`` (the newest frame); returns its seq."""
        with self._lock:
            if self.layout is None or tick.robot is not self.robot or tick.backend != self.backend:
                self._allocate(tick)
            if tick.index <= self._last_index:  # a reset: a new walk
                self._walk += 1
            self._last_index = tick.index
            seq = self.next_seq
            i = seq % self.capacity
            self._encode(tick, i)
            self.next_seq += 1
            if len(self) > self.capacity:
                self.first_seq = self.next_seq - self.capacity
                while self._checkpoint_seqs and self._checkpoint_seqs[0] < self.first_seq:
                    self._checkpoints.pop(self._checkpoint_seqs.pop(0), None)
            return seq

    def wants_checkpoint(self, tick: Tick) -> bool:
        """Whether the state after ``tick`` (the newest frame) should be kept to resume from:
        at each walk's first tick, every CHECKPOINT_S, and after a command changed the walk."""
        return (
            self._dirty
            or tick.index <= 1
            or tick.t - self._last_checkpoint_t >= self.checkpoint_s - 1e-9
            or tick.t < self._last_checkpoint_t
        )

    def mark_dirty(self) -> None:
        """A command changed the walk (a push, gains): checkpoint after the next tick."""
        self._dirty = True

    def checkpoint(self, state: SessionState, t: float) -> None:
        """``state``: the session after the newest frame (at time ``t``)."""
        with self._lock:
            seq = self.last_seq
            if seq is None:
                return
            if seq not in self._checkpoints:
                self._checkpoint_seqs.append(seq)
            self._checkpoints[seq] = state
            self._last_checkpoint_t = t
            self._dirty = False

    def truncate_after(self, seq: int) -> None:
        """Forget the frames after ``seq`` (a resumed walk goes another way from there)."""
        with self._lock:
            seq = min(max(seq, self.first_seq - 1), self.next_seq - 1)
            self.next_seq = seq + 1
            while self._checkpoint_seqs and self._checkpoint_seqs[-1] > seq:
                self._checkpoints.pop(self._checkpoint_seqs.pop(), None)
            self._last_index = int(self._ints[seq % self.capacity, I_INDEX]) if len(self) else -1
            self._walk = int(self._ints[seq % self.capacity, I_WALK]) if len(self) else self._walk
            self._last_checkpoint_t = -math.inf

    # -- the row codec ----------------------------------------------------------------------------
    def _encode(self, tick: Tick, i: int) -> None:
        layout = self.layout
        st, cmd = tick.state, tick.command
        fl, fr = cmd.feet["left"], cmd.feet["right"]
        pose = tick.pose
        contacts = tick.contacts[:CONTACT_SLOTS]
        pull = tick.pull
        nan3 = _NAN3
        parts = [
            (tick.t, st.t - tick.t), st.com, st.com_velocity, st.feet["left"], st.feet["right"],
            (st.feet_yaw["left"], st.feet_yaw["right"]),
            st.applied_contact_force if st.applied_contact_force is not None else nan3,
            st.external_moment if st.external_moment is not None else _ZERO3,
            fl.position, fr.position, fl.velocity, fr.velocity, fl.acceleration, fr.acceleration,
            (fl.yaw, fr.yaw, fl.yaw_rate, fr.yaw_rate), cmd.com_force, cmd.contact_force,
            cmd.xi, cmd.xi_ref, cmd.xi_adj, cmd.v_ref, cmd.v_cmd, cmd.f_hat,
            cmd.v_cmd_rate if cmd.v_cmd_rate is not None else nan3,
        ]  # fmt: skip
        if pose is not None:
            joints = pose.joints
            parts += [pose.base_position, pose.base_wxyz, [joints[j] for j in layout.joints]]
        else:
            parts += [_ZERO3, (1.0, 0.0, 0.0, 0.0)]
        parts.append(tick.adjusted_step.position if tick.adjusted_step is not None else _ZERO3)
        parts.append(tick.recovery_step.position if tick.recovery_step is not None else _ZERO3)
        for point, force in contacts:
            parts += [point, force]
        parts += [_ZERO3] * (2 * (CONTACT_SLOTS - len(contacts)))
        parts.append(tick.cop if tick.cop is not None else nan3)
        parts.append(
            (*pull.target, pull.stiffness, pull.damping, *pull.offset)
            if pull is not None
            else _ZERO8
        )
        pushes = tick.pushes[:PUSH_SLOTS]
        for push in pushes:
            parts.append(push.point)
        parts += [_ZERO3] * (PUSH_SLOTS - len(pushes))
        parts.append((st.mass,))
        self._f32[i] = np.concatenate(parts)
        rec_index = tick.adjusted_index + 1 if tick.recovery_step is not None else -1
        bodies = self._bodies
        flags = (
            F_FELL * tick.fell | F_DONE * tick.done | F_CMD_DONE * bool(cmd.done)
            | F_SUP_L * bool(cmd.support["left"]) | F_SUP_R * bool(cmd.support["right"])
            | F_CON_L * bool(st.in_contact["left"]) | F_CON_R * bool(st.in_contact["right"])
            | F_PULL * (pull is not None) | F_MOMENT * (st.external_moment is not None)
        )  # fmt: skip
        pushed = [bodies.index(p.body) if p.body in bodies else -1 for p in pushes]
        self._ints[i] = [
            tick.index, self._walk, tick.plan_version, tick.adjusted_index, rec_index,
            tick.steps_completed, tick.next_step_index, cmd.phase, cmd.step_index, flags,
            SIDES.index(cmd.swing_side) if cmd.swing_side in SIDES else -1, len(contacts),
            bodies.index(pull.body) if pull is not None and pull.body in bodies else -1,
            *pushed, *([-1] * (PUSH_SLOTS - len(pushed))),
        ]  # fmt: skip
        forces = self._forces[i]
        if pushes:
            forces[:] = 0.0
            for k, push in enumerate(pushes):
                forces[k] = push.force
        elif forces.any():
            forces[:] = 0.0
        if self._phys.shape[1]:
            self._phys[i] = tick.physics
        self._robots[i] = tick.robot
        path = tick.swing_path
        if path is not None and path is not self._path_source:  # a new swing path: kept once
            self._path_source, self._path = path, path.astype(np.float32)
            self._path.flags.writeable = False
        kept = None if path is None else self._path
        self._plans[i] = (tick.plan, tick.nominal_plan, tick.realised_steps, kept)

    def _index(self, seq: int) -> int:
        if not self.first_seq <= seq < self.next_seq:
            raise IndexError(f"frame {seq}: the buffer holds {self.first_seq}…{self.next_seq - 1}")
        return seq % self.capacity

    def tick(self, seq: int) -> Tick:
        """The tick of frame ``seq`` as it was drawn (numbers as float32 copies)."""
        with self._lock:
            i = self._index(seq)
            row = self._f32[i].astype(float)
            ints = self._ints[i].copy()
            forces = self._forces[i].copy()
            phys = self._phys[i].copy() if self._phys.shape[1] else None
            robot = self._robots[i]
            plan, nominal, realised, path = self._plans[i]
            layout = self.layout
        L = layout.slices
        flags = int(ints[I_FLAGS])

        def v(name: str) -> np.ndarray:
            return row[L[name]].copy()

        feet, yaw = v("feet"), v("feet_yaw")
        t = float(row[L["t"]][0])
        state = MeasuredState(
            t=t + float(row[L["dt"]][0]),
            com=v("com"),
            com_velocity=v("com_velocity"),
            feet={"left": feet[:3], "right": feet[3:]},
            feet_yaw={"left": float(yaw[0]), "right": float(yaw[1])},
            in_contact={"left": bool(flags & F_CON_L), "right": bool(flags & F_CON_R)},
            mass=float(row[L["mass"]][0]),
            applied_contact_force=None if np.isnan(row[L["applied"]]).any() else v("applied"),
            external_moment=v("moment") if flags & F_MOMENT else None,
        )
        tp, tv, ta = v("target_p"), v("target_v"), v("target_a")
        ty, tr = v("target_yaw"), v("target_yaw_rate")
        targets = {
            s: FootTarget(tp[3 * k : 3 * k + 3], tv[3 * k : 3 * k + 3], ta[3 * k : 3 * k + 3],
                          float(ty[k]), float(tr[k]))
            for k, s in enumerate(SIDES)
        }  # fmt: skip
        swing = int(ints[I_SWING])
        rate = v("v_cmd_rate")
        command = WalkerCommand(
            t=t,
            support={"left": bool(flags & F_SUP_L), "right": bool(flags & F_SUP_R)},
            feet=targets,
            swing_side=SIDES[swing] if swing >= 0 else None,
            com_force=v("com_force"), contact_force=v("contact_force"), xi=v("xi"),
            xi_ref=v("xi_ref"), xi_adj=v("xi_adj"), v_ref=v("v_ref"), v_cmd=v("v_cmd"),
            f_hat=v("f_hat"), v_cmd_rate=None if np.isnan(rate).any() else rate,
            phase=int(ints[I_PHASE]), step_index=int(ints[I_STEP_INDEX]),
            done=bool(flags & F_CMD_DONE),
        )  # fmt: skip
        pose = None
        if layout.joints:
            q = row[L["joints"]]
            pose = RobotPose(
                v("base"), v("wxyz"), dict(zip(layout.joints, q.tolist(), strict=True))
            )
        pushes = []
        pts = row[L["push_points"]]
        for k in range(PUSH_SLOTS):
            b = int(ints[PUSH0 + k])
            if b >= 0:
                pushes.append(
                    AppliedPush(self._bodies[b], forces[k].copy(), pts[3 * k : 3 * k + 3].copy())
                )
        adj, rec = int(ints[I_ADJ]), int(ints[I_REC])
        adjusted = plan.steps[adj].moved(v("adjusted")) if 0 <= adj < len(plan.steps) else None
        recovery = plan.steps[rec].moved(v("recovery")) if 0 <= rec < len(plan.steps) else None
        contacts = []
        c = L["contacts"].start
        for k in range(int(ints[I_CONTACTS])):
            contacts.append(
                (row[c + 6 * k : c + 6 * k + 3].copy(), row[c + 6 * k + 3 : c + 6 * k + 6].copy())
            )
        cop = v("cop")
        pull = None
        if flags & F_PULL and int(ints[I_PULL]) >= 0:
            p = v("pull")
            pull = Pull(self._bodies[int(ints[I_PULL])], p[:3], float(p[3]), float(p[4]), p[5:8])
        f_ext = sum((p.force for p in pushes), np.zeros(3))
        return Tick(
            index=int(ints[I_INDEX]), t=t, robot=robot, backend=self.backend, state=state,
            command=command, plan=plan, plan_version=int(ints[I_PLAN_VERSION]),
            nominal_plan=nominal, adjusted_index=adj if adjusted is not None else -1,
            adjusted_step=adjusted, recovery_step=recovery, realised_steps=realised,
            steps_completed=int(ints[I_STEPS]), next_step_index=int(ints[I_NEXT]),
            pushes=tuple(pushes), f_ext=f_ext, f_hat=v("f_hat"), pose=pose,
            fell=bool(flags & F_FELL), done=bool(flags & F_DONE), contacts=tuple(contacts),
            cop=None if np.isnan(cop).any() else cop, physics=phys, pull=pull,
            swing_path=None if path is None else path.astype(float),
        )  # fmt: skip

    def physics(self, seq: int) -> np.ndarray | None:
        """The backend's physical state after frame ``seq`` (float64, as measured)."""
        with self._lock:
            return self._phys[self._index(seq)].copy() if self._phys.shape[1] else None

    # -- reading --------------------------------------------------------------------------------
    def walk_of(self, seq: int) -> int:
        with self._lock:
            return int(self._ints[self._index(seq), I_WALK])

    def time_of(self, seq: int) -> float:
        with self._lock:
            return float(self._f32[self._index(seq), self.layout.slices["t"].start])

    def _walk_range(self, seq: int) -> tuple[int, int]:
        """First and last seq of the walk frame ``seq`` belongs to (within the buffer)."""
        walk = self.walk_of(seq)
        walks = self._column(self.first_seq, self.next_seq, ints=I_WALK)
        same = np.flatnonzero(walks == walk)
        return self.first_seq + int(same[0]), self.first_seq + int(same[-1])

    def _column(self, a: int, b: int, *, ints: int | None = None, f32: slice | None = None):
        """Rows a … b − 1 (seqs) of one column, in order."""
        idx = np.arange(a, b) % self.capacity
        if ints is not None:
            return self._ints[idx, ints]
        return self._f32[idx, f32]

    def window(self, seq: int, seconds: float, points: int = 400) -> dict[str, np.ndarray]:
        """The plotted signals of the ``seconds`` before frame ``seq`` within its walk (about
        ``points`` samples): t, and (N, 3) per signal of SIGNALS_3D, and dcm_error (N,)."""
        with self._lock:
            self._index(seq)
            first, _ = self._walk_range(seq)
            n = max(1, int(round(seconds / self.dt)))
            a = max(first, seq - n + 1)
            stride = max(1, (seq - a + 1) // points)
            seqs = np.arange(seq, a - 1, -stride)[::-1]  # the frame itself is the last sample
            idx = seqs % self.capacity
            L = self.layout.slices
            rows = self._f32[idx]
            out: dict[str, np.ndarray] = {"t": rows[:, L["t"].start].astype(float)}
            for name in SIGNALS_3D:
                if name == "f_ext":
                    out[name] = self._forces[idx].sum(axis=1)
                else:
                    out[name] = rows[:, L[name]].astype(float)
        out["dcm_error"] = np.linalg.norm(out["xi"] - out["xi_ref"], axis=1)
        return out

    def seq_back(self, seconds_back: float) -> int | None:
        """The frame ``seconds_back`` before the newest (clamped into the buffer)."""
        with self._lock:
            if not len(self):
                return None
            k = int(round(max(seconds_back, 0.0) / self.dt))
            return max(self.first_seq, self.next_seq - 1 - k)

    def footstep(self, seq: int, direction: int) -> int | None:
        """The frame of the next (``direction`` +1) or previous (−1) touchdown from ``seq``
        within its walk (the first frame with one more footstep landed), or None."""
        with self._lock:
            first, last = self._walk_range(seq)
            steps = self._column(first, last + 1, ints=I_STEPS)
            k = seq - first
            land = np.flatnonzero(np.diff(steps) != 0) + 1  # first frames after a landing
            if direction > 0:
                after = land[land > k]
                return first + int(after[0]) if len(after) else None
            before = land[land < k]
            return first + int(before[-1]) if len(before) else first if k > 0 else None

    def recent_push(self, seq: int, seconds: float) -> tuple[float, str, np.ndarray, bool] | None:
        """The last external force in the ``seconds`` up to frame ``seq`` (its walk): (time it
        started, body, force at its peak, whether a drag's spring pulled), or None."""
        with self._lock:
            first, _ = self._walk_range(seq)
            a = max(first, seq - int(round(seconds / self.dt)))
            idx = np.arange(a, seq + 1) % self.capacity
            bodies = self._ints[idx, PUSH0]
            pushed = np.flatnonzero(bodies >= 0)
            if not len(pushed):
                return None
            end = pushed[-1]
            start = end
            while start > 0 and bodies[start - 1] >= 0:
                start -= 1
            forces = self._forces[idx[start : end + 1], 0]
            peak = forces[int(np.argmax(np.linalg.norm(forces, axis=1)))]
            t = float(self._f32[idx[start], self.layout.slices["t"].start])
            pulled = bool(self._ints[idx[end], I_FLAGS] & F_PULL)
            return t, self._bodies[int(bodies[end])], peak.copy(), pulled

    # -- resuming ---------------------------------------------------------------------------------
    def resume_from(self, seq: int) -> tuple[SessionState, list[dict[str, np.ndarray]], int]:
        """The last checkpoint at or before frame ``seq``, the forces of the ticks after it up
        to ``seq`` (to replay), and the frame resumed (``seq``, or the first checkpoint when
        ``seq`` is older)."""
        with self._lock:
            self._index(seq)
            if not self._checkpoint_seqs:
                raise LookupError("nothing to resume from yet")
            k = bisect.bisect_right(self._checkpoint_seqs, seq) - 1
            if k < 0:
                seq = self._checkpoint_seqs[0]
                k = 0
            c = self._checkpoint_seqs[k]
            forces = []
            for s in range(c + 1, seq + 1):
                i = s % self.capacity
                forces.append({
                    self._bodies[int(b)]: self._forces[i, j].copy()
                    for j, b in enumerate(self._ints[i, PUSH0 : PUSH0 + PUSH_SLOTS]) if b >= 0
                })  # fmt: skip
            return self._checkpoints[c], forces, seq


CHECKPOINT_BYTES = 16 * 1024  # about what one SessionState holds (a walker copy, the backend's
# state): measured 13–17 KiB with tracemalloc for the point mass and Talos
