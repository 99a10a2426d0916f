"""Rerun recording of a walking session (rerun 0.41 API) to an ``.rrd`` file.

A :class:`Recorder` hooks into :attr:`Session.on_tick` (chaining any callback already there) and
logs, every ``log_dt_s`` of simulated time on the ``sim_time`` timeline:

* ``plots/x``, ``plots/y``, ``plots/z``: CoM, measured DCM ξ (eq. 1), ξ_ref (eq. 48), ξ_adj
  (eqs. 33, 49), VRP reference v_ref (eq. 47) and command v_cmd (eqs. 24, 41) per axis;
  ``plots/dcm_error`` |ξ − ξ_ref|; ``plots/force`` applied and estimated (eq. 45) force;
* ``world/...``: the same points in 3-D with short trails, the planned DCM/VRP references as line
  strips (re-logged when a touchdown commits a footstep), footsteps as boxes (planned = nominal,
  adjusted = the target being adjusted right now, realised = where each foot landed), the applied
  external force and the estimated force as arrows at the CoM;
* ``world/terrain``: the preset's stairs and boxes (:mod:`dcmviz.gait.terrain`) as solid boxes;
* ``world/robot/<model>/<mesh>``: the humanoid's visual meshes (:mod:`dcmviz.robots.visual`, the
  model the dashboard draws) as ``rr.Mesh3D``, logged once when the first humanoid tick arrives,
  each posed per sample from ``tick.pose`` by a ``Transform3D``; for the point mass two legs.

The recorder reads the session's :class:`~dcmviz.session.tick.Tick` records and, at :meth:`Recorder.start`,
its robot spec and nominal plan; nothing else of the session.

Each recorder owns a dedicated :class:`rerun.RecordingStream`, so several recordings can coexist.
A stopped recorder's stream is kept for the next recording: rerun never frees a stream created
from Python (it only disconnects it; its threads and buffers stay, about 2 MB and two threads
per recording), so streams are reused instead of one being created per recording.
The dashboard's Record toggle calls :meth:`Recorder.start` and :meth:`Recorder.stop`.
"""

from __future__ import annotations

import math
import threading
import uuid
from collections import defaultdict, deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from dcmviz.gait.terrain import terrain_of
from dcmviz.robots import Robot
from dcmviz.robots.visual import RobotVisual
from dcmviz.session import Session
from dcmviz.session.signals import FOOTSTEP_COLORS, SIDE_COLORS, color
from dcmviz.session.signals import TERRAIN_COLOR as TERRAIN_RGB
from dcmviz.session.tick import Tick

LOG_DT_S = 0.01  # sim seconds between logged samples
TRAIL_SAMPLES = 200  # 3-D trails show the last 2 s
TRAIL_EVERY = 5  # samples between trail updates
FLUSH_SAMPLES = 200  # samples buffered before they are sent as columns
FORCE_SCALE_M_PER_N = 0.005  # arrow length per newton

SERIES = ("com", "xi", "xi_ref", "xi_adj", "v_ref", "v_cmd")
SERIES_COLORS = {key: color(key) for key in SERIES}  # the dashboard's (session.signals)
TERRAIN_COLOR = (*TERRAIN_RGB, 255)
FOOT_COLORS = {
    "planned": (*FOOTSTEP_COLORS["planned"], 120),
    "plan": (*SIDE_COLORS["left"], 150),
    "adjusted": (*FOOTSTEP_COLORS["adjusted"], 200),
    "realised": (*FOOTSTEP_COLORS["realised"], 220),
}


# ---------------------------------------------------------------------------------------------
# the streams: rerun keeps every RecordingStream made from Python alive until the process ends
# (rerun issue #2116: dropped streams are disconnected, never freed), so a stopped recorder's
# stream waits here for the next recording; there are never more than recordings at once.

_IDLE_STREAMS: list[rr.RecordingStream] = []
_STREAMS_LOCK = threading.Lock()


def _open_stream() -> rr.RecordingStream:
    """A disconnected stream of an earlier recording (its timeline cleared), or a new one."""
    with _STREAMS_LOCK:
        stream = _IDLE_STREAMS.pop() if _IDLE_STREAMS else None
    if stream is None:
        return rr.RecordingStream("dcmviz", recording_id=str(uuid.uuid4()))
    stream.reset_time()
    return stream


def _close_stream(stream: rr.RecordingStream) -> None:
    """Flush and close the stream's file, and keep the stream for the next recording."""
    stream.flush()
    stream.disconnect()
    with _STREAMS_LOCK:
        _IDLE_STREAMS.append(stream)


# ---------------------------------------------------------------------------------------------
# the recorder


class Recorder:
    """Logs a :class:`~dcmviz.session.Session` to an ``.rrd`` file while it runs."""

    def __init__(self, *, log_dt_s: float = LOG_DT_S, meshes: bool = True) -> None:
        self.log_dt_s = float(log_dt_s)
        self.meshes = meshes
        self.stream: rr.RecordingStream | None = None
        self.path: Path | None = None
        self.samples = 0
        self._session = None
        self.url: str | None = None  # the live stream's address (start's serve_port)

    @property
    def recording(self) -> bool:
        return self.stream is not None

    # -- lifecycle ------------------------------------------------------------------------------
    def start(self, session: Session, path: str | Path, *, serve_port: int | None = None) -> None:
        """Open ``path`` (.rrd), log the static scene and chain :meth:`on_tick` into the session.

        With ``serve_port`` the recording is also served live over gRPC on 127.0.0.1 at that
        port while it runs: ``rerun rerun+http://127.0.0.1:PORT/proxy`` (:attr:`url`) connects
        a rerun viewer, which receives everything logged so far and then the live stream."""
        if self.stream is not None:
            raise RuntimeError("Recorder.start: already recording; call stop() first")
        self.path = Path(path)
        self.stream = _open_stream()
        self.url = None
        if serve_port is None:
            self.stream.save(self.path)
        else:
            server = rr.GrpcServerSink(bind_ip="127.0.0.1", port=int(serve_port),
                                       server_memory_limit="256MiB")  # fmt: skip
            self.stream.set_sinks(rr.FileSink(self.path), server)
            self.url = f"rerun+http://127.0.0.1:{int(serve_port)}/proxy"
        self._session = session
        self._next_t = -math.inf
        self._last_t = -math.inf
        self._offset = 0.0  # session time of the walk's t = 0 (grows at every reset)
        self.resets = 0
        self._plan_id = None
        self._n_records = -1
        self._trail: dict[str, deque] = {k: deque(maxlen=TRAIL_SAMPLES) for k in ("com", "xi")}
        self.samples = 0
        self._visual: RobotVisual | None = None  # the humanoid whose meshes are logged
        self._buf: dict[str, list] = defaultdict(list)
        self._had_target = False
        self._last_record = None
        self._log_static(session)
        self._unsubscribe = session.subscribe(self.on_tick)

    def stop(self) -> Path:
        """Detach from the session, flush and close the file; returns its path."""
        if self.stream is None:
            raise RuntimeError("Recorder.stop: not recording")
        self._unsubscribe()
        self._flush()
        stream, self.stream, self._session = self.stream, None, None
        _close_stream(stream)
        return self.path

    # -- logging --------------------------------------------------------------------------------
    def _log_static(self, session: Session) -> None:
        """What never changes: plot styles, point and arrow styles (not their positions: static
        data shadows temporal data of the same component), the nominal footsteps."""
        rec = self.stream
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        for axis in ("x", "y", "z"):
            rec.log(
                f"plots/{axis}",
                rr.SeriesLines(
                    names=[f"{k} {axis}" for k in SERIES],
                    colors=[SERIES_COLORS[k] for k in SERIES],
                ),
                static=True,
            )
        rec.log("plots/dcm_error", rr.SeriesLines(names=["|ξ − ξ_ref| (m)"]), static=True)
        rec.log(
            "plots/force",
            rr.SeriesLines(
                names=["F_ext x", "F_ext y", "F_ext z", "F̂ x", "F̂ y", "F̂ z"],
                colors=[(230, 50, 50), (50, 160, 50), (50, 50, 230)] * 2,
                widths=[2.0, 2.0, 2.0, 1.0, 1.0, 1.0],
            ),
            static=True,
        )
        rec.log(
            "world/points",
            rr.Points3D.from_fields(
                radii=[0.03, 0.02, 0.015, 0.015, 0.015, 0.02],
                colors=[SERIES_COLORS[k] for k in SERIES],
                labels=list(SERIES),
            ),
            static=True,
        )
        rec.log(
            "world/forces",
            rr.Arrows3D.from_fields(
                colors=[color("f_ext"), color("f_hat")],
                radii=[0.01, 0.008],
                labels=["F_ext", "F̂"],
            ),
            static=True,
        )
        rec.log(
            "world/robot/legs",
            rr.LineStrips3D.from_fields(colors=[(90, 90, 90)], radii=0.01),
            static=True,
        )
        spec = session.spec
        self._half_size = (0.5 * spec.foot_length_m, 0.5 * spec.foot_width_m, 0.004)
        nominal = session.nominal_plan
        rec.log("world/footsteps/planned", self._boxes(nominal.steps, "planned"), static=True)
        terrain = terrain_of(session.config.terrain)
        if not terrain.flat:  # the preset's stairs and boxes, solid, from the floor up
            solids = [box.solid for box in terrain.boxes]
            rec.log(
                "world/terrain",
                rr.Boxes3D(
                    centers=[c for c, _ in solids],
                    half_sizes=[h for _, h in solids],
                    rotation_axis_angles=[
                        rr.RotationAxisAngle(axis=(0, 0, 1), radians=float(b.yaw))
                        for b in terrain.boxes
                    ],
                    colors=[TERRAIN_COLOR] * len(solids),
                    fill_mode=rr.components.FillMode.Solid,
                ),
                static=True,
            )

    def _boxes(self, steps: Any, kind: str) -> rr.Boxes3D:
        centers = [
            np.asarray(s.position, float) + np.array([0, 0, self._half_size[2]]) for s in steps
        ]
        return rr.Boxes3D(
            centers=centers if centers else np.zeros((0, 3)),
            half_sizes=[self._half_size] * len(centers),
            rotation_axis_angles=[
                rr.RotationAxisAngle(axis=(0, 0, 1), radians=float(s.yaw)) for s in steps
            ],
            colors=[FOOT_COLORS[kind]] * len(centers),
            fill_mode=rr.components.FillMode.Solid if kind != "planned" else None,
        )

    def on_tick(self, tick: Tick) -> None:
        """Buffer one decimated sample (called after every tick); rare events are logged now.

        The ``sim_time`` timeline is the session's clock: when the walk restarts (a reset, a fall,
        a new preset) its time starts again at 0, and the recording continues after the last
        sample instead of waiting for the walk's time to pass its earlier maximum.
        """
        if self.stream is None:
            return
        cmd = tick.command
        if tick.t < self._last_t - 1e-9:  # the walk restarted
            self._offset += self._last_t + self.log_dt_s
            self._next_t = -math.inf
            self.resets += 1
            self._plan_id = None
            self._n_records = -1
        self._last_t = tick.t
        if tick.t < self._next_t - 1e-9:
            return
        self._next_t = tick.t + self.log_dt_s
        t = self._offset + tick.t
        self._show_robot(tick.robot if tick.pose is not None else None, t)  # may flush: first
        rec = self.stream
        state = tick.state
        values = {
            "com": np.asarray(state.com, float),
            "xi": np.asarray(cmd.xi, float),
            "xi_ref": np.asarray(cmd.xi_ref, float),
            "xi_adj": np.asarray(cmd.xi_adj, float),
            "v_ref": np.asarray(cmd.v_ref, float),
            "v_cmd": np.asarray(cmd.v_cmd, float),
        }
        f_ext, f_hat = tick.f_ext, tick.f_hat
        com = values["com"]

        # per-sample data goes to column buffers, sent in batches (rr.send_columns is far cheaper
        # than one rr.log per entity and sample)
        buf = self._buf
        buf["t"].append(t)
        points = np.array([values[k] for k in SERIES])
        for i, axis in enumerate(("x", "y", "z")):
            buf[f"plots/{axis}"].append(points[:, i])
        buf["plots/dcm_error"].append(float(np.linalg.norm(cmd.xi - cmd.xi_ref)))
        buf["plots/force"].append(np.concatenate([f_ext, f_hat]))
        buf["points"].append(points)
        buf["arrows"].append(np.array([f_ext, f_hat]) * FORCE_SCALE_M_PER_N)
        buf["com"].append(com)
        if tick.pose is not None:
            buf["robot_t"].append(t)
            buf["robot"].append(self._visual.in_world(tick.pose))
        else:
            buf["legs_t"].append(t)
            buf["legs"].append([[state.feet[s], com] for s in ("left", "right")])

        # rare or slow-changing things are logged directly at this instant
        rec.set_time("sim_time", duration=t)
        for key in self._trail:
            self._trail[key].append(values[key])
        if self.samples % TRAIL_EVERY == 0:
            for key, trail in self._trail.items():
                rec.log(
                    f"world/trails/{key}",
                    rr.LineStrips3D([np.array(trail)], colors=[SERIES_COLORS[key]]),
                )
        plan = tick.plan
        if tick.plan_version != self._plan_id:  # a touchdown committed a footstep: new references
            self._plan_id = tick.plan_version
            ts = np.linspace(0.0, plan.preview.duration, 400)
            for name, curve, key in (
                ("dcm", plan.preview.dcm(ts), "xi_ref"),
                ("vrp", plan.preview.vrp(ts), "v_ref"),
            ):
                rec.log(
                    f"world/reference/{name}",
                    rr.LineStrips3D([curve], colors=[SERIES_COLORS[key]]),
                )
            rec.log("world/footsteps/plan", self._boxes(plan.steps, "plan"))
        target = tick.adjusted_step
        if target is not None and self.samples % TRAIL_EVERY == 0:
            rec.log("world/footsteps/adjusted", self._boxes([target], "adjusted"))
        elif target is None and self._had_target:
            rec.log("world/footsteps/adjusted", rr.Clear(recursive=False))
        self._had_target = target is not None
        records = tick.realised_steps
        if len(records) != self._n_records or (records and records[-1] is not self._last_record):
            self._last_record = records[-1] if records else None
            self._n_records = len(records)
            placed = [_Placed(r.position, 0.0) for r in records]
            rec.log("world/footsteps/realised", self._boxes(placed, "realised"))
        self.samples += 1
        if len(buf["t"]) >= FLUSH_SAMPLES:
            self._flush()

    def _show_robot(self, robot: Robot | None, t: float) -> None:
        """Log the meshes of humanoid ``robot`` (None: no humanoid) once; clear the previous one."""
        current = None if self._visual is None else self._visual.model_name
        model = None if robot is None else robot.name
        if model == current:
            return
        self._flush()  # buffered poses belong to the robot shown so far
        rec = self.stream
        rec.set_time("sim_time", duration=t)
        if current is not None:
            rec.log(f"world/robot/{current}", rr.Clear(recursive=True))
        self._visual = None if robot is None else robot.visual
        if self._visual is None or not self.meshes:
            return
        for mesh in self._visual.meshes:
            rec.log(
                f"world/robot/{model}/{mesh.name}",
                rr.Mesh3D(
                    vertex_positions=mesh.vertices,
                    triangle_indices=mesh.faces,
                    vertex_normals=mesh.normals,
                    albedo_factor=mesh.color,
                ),
            )

    def _flush(self) -> None:
        """Send the buffered samples as columns."""
        buf = self._buf
        n = len(buf["t"])
        if self.stream is None or n == 0:
            return
        rec = self.stream
        index = [rr.TimeColumn("sim_time", duration=np.array(buf["t"]))]
        for entity in ("plots/x", "plots/y", "plots/z", "plots/force"):
            rec.send_columns(
                entity, indexes=index, columns=rr.Scalars.columns(scalars=np.array(buf[entity]))
            )
        rec.send_columns(
            "plots/dcm_error",
            indexes=index,
            columns=rr.Scalars.columns(scalars=np.array(buf["plots/dcm_error"])),
        )
        k = len(SERIES)
        rec.send_columns(
            "world/points",
            indexes=index,
            columns=rr.Points3D.columns(positions=np.concatenate(buf["points"])).partition([k] * n),
        )
        com = np.array(buf["com"])
        rec.send_columns(
            "world/forces",
            indexes=index,
            columns=rr.Arrows3D.columns(
                vectors=np.concatenate(buf["arrows"]), origins=np.repeat(com, 2, axis=0)
            ).partition([2] * n),
        )
        if buf["robot"]:
            model = self._visual.model_name
            robot_index = [rr.TimeColumn("sim_time", duration=np.array(buf["robot_t"]))]
            position = np.array([p.position for p in buf["robot"]])  # (samples, meshes, 3)
            xyzw = np.roll(np.array([p.wxyz for p in buf["robot"]]), -1, axis=2)
            for j, mesh in enumerate(self._visual.meshes):
                rec.send_columns(
                    f"world/robot/{model}/{mesh.name}",
                    indexes=robot_index,
                    columns=rr.Transform3D.columns(
                        translation=position[:, j], quaternion=xyzw[:, j]
                    ),
                )
        if buf["legs"]:
            strips = np.array(buf["legs"], float).reshape(-1, 2, 3)  # two legs per sample
            rec.send_columns(
                "world/robot/legs",
                indexes=[rr.TimeColumn("sim_time", duration=np.array(buf["legs_t"]))],
                columns=rr.LineStrips3D.columns(strips=list(strips)).partition(
                    [2] * len(buf["legs"])
                ),
            )
        self._buf = defaultdict(list)


@dataclass(frozen=True)
class _Placed:
    position: np.ndarray
    yaw: float


def record_session(session: Any, path: str | Path, duration: float, **kwargs: Any) -> Path:
    """Run ``session`` for ``duration`` s while recording to ``path``; returns the path."""
    recorder = Recorder(**kwargs)
    recorder.start(session, path)
    try:
        session.run(duration)
    finally:
        out = recorder.stop()
    return out
