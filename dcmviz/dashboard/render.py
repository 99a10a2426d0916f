"""The render thread: draws the simulation loop's latest snapshot into the scene at ≥ 30 fps.

The humanoid (or the point mass), the floor overlays of ξ, ξ_adj and the commanded VRP, the force
arrows, the adjusted (ghost) and realised footsteps, the live DCM plot and the status line.  It
only reads :class:`~dcmviz.dashboard.loop.Snapshot` objects; it never touches the session.  The
walked plan is drawn by :class:`~dcmviz.dashboard.plan_view.PlanView`.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import viser

from dcmviz.dashboard import scene as draw
from dcmviz.dashboard.loop import SimLoop, Snapshot
from dcmviz.dashboard.plots import LivePlot
from dcmviz.dashboard.preview import Sole
from dcmviz.dashboard.robot_view import BodyClick, RobotView
from dcmviz.dashboard.status import StatusLine
from dcmviz.robots import get_spec
from dcmviz.visual import robot_visual

RENDER_FPS = 40.0  # scene updates per second (≥ 30 with margin for scheduling jitter)
STATUS_DT_S = 0.25
FOLLOW_DT_S = 0.1  # camera-follow updates (per client, so kept slow)
FLOOR_LIFT_M = 0.012  # overlays on the floor sit this high (above the footsteps)


def dz_vrp(snap: Snapshot) -> float:
    """Δz_vrp = g b² of the walked plan (m): how far the VRP lies above the floor."""
    return snap.plan.dz_vrp if snap.plan is not None else 0.0


def floor_drop(snap: Snapshot) -> np.ndarray:
    """How far ξ, ξ_adj and the VRP are moved down to lie on the floor (just above the soles):
    they sit about Δz_vrp up, inside the robot, and read better against the footsteps."""
    return np.array([0.0, 0.0, dz_vrp(snap) - FLOOR_LIFT_M])


def arrow_points(pushes: tuple) -> np.ndarray:
    """(n, 2, 3) arrows of the applied forces, each ending just outside the body it pushes."""
    pts = []
    for _, point, force in pushes:
        u = force / max(float(np.linalg.norm(force)), 1e-9)
        tip = point - draw.ARROW_STANDOFF_M * u
        pts.append([tip - force / draw.NEWTONS_PER_METRE, tip])
    return np.array(pts)


class SimView:
    """Draws snapshots in a daemon thread; ``fps`` and ``frames_drawn`` measure it."""

    def __init__(
        self,
        server: viser.ViserServer,
        loop: SimLoop,
        *,
        live_plot: LivePlot,
        status: StatusLine,
        gui_follow: viser.GuiInputHandle[bool],
        on_body_click: BodyClick,
    ) -> None:
        self.server = server
        self.loop = loop
        self.live_plot = live_plot
        self.status = status
        self.gui_follow = gui_follow
        self.on_body_click = on_body_click
        self.robot_view: RobotView | None = None
        self.fps = 0.0
        self.frames_drawn = 0
        self._markers: dict[str, viser.SceneNodeHandle] = {}
        self._force_shown = False
        self._fhat_shown = False
        self._follow_anchor: np.ndarray | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="dcmviz-render", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)

    def _run(self) -> None:
        period = 1.0 / RENDER_FPS
        last: Snapshot | None = None
        last_status = 0.0
        last_history = None
        last_follow = 0.0
        frames, fps_t0 = 0, time.perf_counter()
        next_frame = fps_t0
        while not self._stop.is_set():
            t0 = time.perf_counter()
            snap = self.loop.snapshot
            if snap is not last:
                try:
                    self.draw_snapshot(snap, last)
                except Exception as err:  # noqa: BLE001 - never let drawing kill the thread
                    print(f"dcmviz: drawing failed: {err!r}")
                if snap.history is not last_history and snap.history:
                    self.live_plot.draw(snap.history)
                    last_history = snap.history
                last = snap
                frames += 1
                self.frames_drawn += 1
            if t0 - fps_t0 >= 1.0:
                self.fps = frames / (t0 - fps_t0)
                frames, fps_t0 = 0, t0
            if t0 - last_follow >= FOLLOW_DT_S:
                self._follow(snap)
                last_follow = t0
            if t0 - last_status >= STATUS_DT_S or self.status.is_new(snap):
                self.status.show(snap, self.fps, t0)
                last_status = t0
            next_frame = max(next_frame + period, time.perf_counter() - period)
            time.sleep(max(0.0, next_frame - time.perf_counter()))

    def draw_snapshot(self, snap: Snapshot, last: Snapshot | None) -> None:
        """Robot, overlays, force arrows and footstep markers of one snapshot."""
        if not self._markers:
            self._make_markers()
        self.draw_robot(snap)
        drop = floor_drop(snap)
        for name, value in (("xi", snap.xi), ("xi_adj", snap.xi_adj), ("v_cmd", snap.v_cmd)):
            handle = self._markers[name]
            handle.visible = value is not None
            if value is not None:
                handle.position = value - drop
        self.draw_forces(snap)
        spec = get_spec(snap.robot)
        for field, color, opacity, lift in (
            ("adjusted_steps", draw.GHOST_COLOR, 0.25, 0.004),
            ("realised_steps", draw.REALISED_COLOR, 0.6, 0.008),
        ):
            steps = getattr(snap, field)
            if last is not None and _steps_key(steps) == _steps_key(getattr(last, field)):
                continue
            soles = [Sole(s.side, np.asarray(s.position), s.yaw, i) for i, s in enumerate(steps)]
            draw.draw_step_markers(
                self.server.scene, f"/sim/{field.removesuffix('_steps')}", soles,
                spec.foot_length_m, spec.foot_width_m, color, opacity=opacity, lift=lift,
            )  # fmt: skip

    def draw_robot(self, snap: Snapshot) -> None:
        """The humanoid's meshes, or the point mass (a ball and its pendulum leg)."""
        tick = snap.tick
        pose = tick.pose if tick is not None else None
        com, leg = self._markers["com"], self._markers["lip_leg"]
        if pose is not None:
            if self.robot_view is None or self.robot_view.model != snap.robot:
                self._load_robot_view(snap.robot)
            self.robot_view.set_visible(True)
            self.robot_view.update(pose)
            com.visible = leg.visible = False
            return
        if self.robot_view is not None:
            self.robot_view.set_visible(False)
        if snap.com is None:
            return
        com.visible = True
        com.position = snap.com
        if snap.v_cmd is not None:  # the pendulum "leg": floor point below the VRP → CoM
            floor = snap.v_cmd - [0.0, 0.0, dz_vrp(snap)]
            leg.points = np.array([[floor, snap.com]], np.float32)
            leg.visible = True

    def draw_forces(self, snap: Snapshot) -> None:
        """Applied forces (at the pushed bodies) and the observer's estimate (above the head)."""
        scene = self.server.scene
        if snap.pushes:
            scene.add_arrows(
                "/sim/force", arrow_points(snap.pushes), draw.FORCE_COLOR, shaft_radius=0.018,
                head_radius=0.045, head_length=0.09,
            )  # fmt: skip
            self._force_shown = True
        elif self._force_shown:
            scene.add_arrows("/sim/force", np.zeros((1, 2, 3)), draw.FORCE_COLOR, visible=False)
            self._force_shown = False
        if snap.f_hat is None or snap.com is None:
            return
        if float(np.linalg.norm(snap.f_hat)) > 2.0:
            origin = snap.com + [0.0, 0.0, 0.95]
            scene.add_arrows(
                "/sim/f_hat", np.array([[origin, origin + snap.f_hat / draw.NEWTONS_PER_METRE]]),
                draw.OBSERVER_COLOR, shaft_radius=0.012, head_radius=0.035, head_length=0.07,
            )  # fmt: skip
            self._fhat_shown = True
        elif self._fhat_shown:
            scene.add_arrows("/sim/f_hat", np.zeros((1, 2, 3)), (0, 0, 0), visible=False)
            self._fhat_shown = False

    def _follow(self, snap: Snapshot) -> None:
        """Move every client's camera by the robot's horizontal displacement since last time."""
        pose = snap.tick.pose if snap.tick is not None else None
        anchor = pose.base_position if pose is not None else snap.com
        if anchor is None:
            return
        here = np.array([anchor[0], anchor[1], 0.0])
        last, self._follow_anchor = self._follow_anchor, here
        if not self.gui_follow.value or last is None:
            return
        delta = here - last
        if float(np.linalg.norm(delta)) < 1e-4:  # standing still
            return
        for client in list(self.server.get_clients().values()):
            try:
                # moving the camera position translates the view (the client keeps the
                # look-at offset); setting look_at as well would move the target twice
                client.camera.position = client.camera.position + delta
            except Exception:  # noqa: BLE001 - a client that just closed
                pass

    def _make_markers(self) -> None:
        scene = self.server.scene
        self._markers = {
            "xi": scene.add_icosphere("/sim/xi", radius=0.028, color=draw.MEASURED_DCM_COLOR),
            "xi_adj": scene.add_icosphere(
                "/sim/xi_adj", radius=0.022, color=draw.ADJUSTED_DCM_COLOR
            ),
            "v_cmd": scene.add_icosphere(
                "/sim/v_cmd", radius=0.022, color=draw.COMMANDED_VRP_COLOR
            ),
            "com": scene.add_icosphere(
                "/sim/com", radius=0.09, color=(120, 120, 130), visible=False
            ),
            "lip_leg": scene.add_line_segments(
                "/sim/lip_leg",
                np.zeros((1, 2, 3), np.float32),
                (90, 90, 90),
                thickness=0.012,
                visible=False,
            ),  # fmt: skip
        }
        # the point mass is clickable like the humanoid: a push at the CoM ("torso")
        self._markers["com"].on_click(lambda event: self.on_body_click("torso", event))

    def _load_robot_view(self, model: str) -> None:
        if self.robot_view is not None:
            self.robot_view.remove()
        self.robot_view = RobotView(self.server, robot_visual(model), self.on_body_click)


def _steps_key(steps: tuple) -> tuple:
    return tuple((s.side, round(float(s.position[0]), 4), round(float(s.position[1]), 4))
                 for s in steps)  # fmt: skip
