"""The render thread: draws the simulation loop's latest snapshot into the scene at ≥ 30 fps.

The humanoid (or the point mass), the floor overlays of ξ, ξ_adj and the commanded VRP, the force
arrows, the adjusted (ghost) and realised footsteps, the live DCM plot and the status line.  It
only reads :class:`~dcmviz.dashboard.loop.Snapshot` objects; it never touches the session.
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from dcmviz import GRAVITY
from dcmviz.dashboard import scene as draw
from dcmviz.dashboard.loop import Snapshot
from dcmviz.dashboard.preview import Sole
from dcmviz.dashboard.robot_view import RobotView
from dcmviz.robots import get_spec

if TYPE_CHECKING:
    from dcmviz.dashboard.dashboard import Dashboard

RENDER_FPS = 40.0  # scene updates per second (≥ 30 with margin for scheduling jitter)
STATUS_DT_S = 0.25
FOLLOW_DT_S = 0.1  # camera-follow updates (per client, so kept slow)


class SimView:
    """Draws snapshots in a daemon thread; ``fps`` and ``frames_drawn`` measure it."""

    def __init__(self, dashboard: Dashboard) -> None:
        self.dashboard = dashboard
        self.server = dashboard.server
        self.robot_view: RobotView | None = None
        self.fps = 0.0
        self.frames_drawn = 0
        self._markers_ready = False
        self._markers: dict[str, Any] = {}
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
        last_plan = None
        last_follow = 0.0
        frames, fps_t0 = 0, time.perf_counter()
        next_frame = fps_t0
        while not self._stop.is_set():
            t0 = time.perf_counter()
            snap = self.dashboard.loop.snapshot
            if snap is not last:
                try:
                    self.draw_snapshot(snap, last)
                except Exception as err:  # noqa: BLE001 - never let drawing kill the thread
                    print(f"dcmviz: drawing failed: {err!r}")
                d = self.dashboard
                if (
                    snap.plan is not None
                    and snap.plan is not last_plan
                    and d.config.gait.mode == "continuous"
                    and snap.version == d.version
                ):  # the receding horizon moved: preview what the walker follows now
                    d.preview.submit(d.version, snap.plan, d.config, time.perf_counter())
                last_plan = snap.plan
                if snap.history is not last_history and snap.history:
                    self.dashboard.live_plot.draw(snap.history)
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
            if t0 - last_status >= STATUS_DT_S:
                self.dashboard.gui_status.content = self.status_text(snap)
                last_status = t0
            next_frame = max(next_frame + period, time.perf_counter() - period)
            time.sleep(max(0.0, next_frame - time.perf_counter()))

    def draw_snapshot(self, snap: Snapshot, last: Snapshot | None) -> None:
        """Robot, overlays, force arrows and footstep markers of one snapshot."""
        scene = self.server.scene
        if not self._markers_ready:
            self._make_markers()
        if snap.backend == "mujoco" and snap.base_position is not None:
            if self.robot_view is None or self.robot_view.model != snap.robot:
                self._load_robot_view(snap.robot)
            self.robot_view.set_visible(True)
            self.robot_view.update(snap.base_position, snap.base_wxyz, snap.joints)
            self._com_marker.visible = False
        else:
            if self.robot_view is not None:
                self.robot_view.set_visible(False)
            if snap.com is not None:
                self._com_marker.visible = True
                self._com_marker.position = snap.com
                if snap.v_cmd is not None:  # the pendulum "leg": floor point below the VRP → CoM
                    dz = GRAVITY * self.dashboard.config.dcm.b**2
                    scene.add_line_segments(
                        "/sim/lip_leg", np.array([[snap.v_cmd - [0.0, 0.0, dz], snap.com]]),
                        (90, 90, 90), thickness=0.012,
                    )  # fmt: skip
        # ξ, ξ_adj and the commanded VRP sit ~Δz_vrp up, inside the robot: draw them on the floor
        # (shifted down by Δz_vrp = g b²), where they read against the footsteps
        down = np.array([0.0, 0.0, GRAVITY * self.dashboard.config.dcm.b**2 - 0.012])
        for name, value in (("xi", snap.xi), ("xi_adj", snap.xi_adj), ("v_cmd", snap.v_cmd)):
            handle = self._markers[name]
            if value is None:
                handle.visible = False
            else:
                handle.visible = True
                handle.position = value - down
        pushes = snap.pushes
        if pushes:
            # each arrow ends just outside the body it pushes (its head stays visible)
            pts = []
            for _, p, f in pushes:
                u = f / max(float(np.linalg.norm(f)), 1e-9)
                tip = p - draw.ARROW_STANDOFF_M * u
                pts.append([tip - f / draw.NEWTONS_PER_METRE, tip])
            scene.add_arrows(
                "/sim/force", np.array(pts), draw.FORCE_COLOR, shaft_radius=0.018,
                head_radius=0.045, head_length=0.09,
            )  # fmt: skip
            self._force_shown = True
        elif getattr(self, "_force_shown", False):
            scene.add_arrows("/sim/force", np.zeros((1, 2, 3)), draw.FORCE_COLOR, visible=False)
            self._force_shown = False
        if snap.f_hat is not None and snap.com is not None:
            fh = snap.f_hat
            if float(np.linalg.norm(fh)) > 2.0:
                origin = snap.com + [0.0, 0.0, 0.95]  # above the head, where it is visible
                scene.add_arrows(
                    "/sim/f_hat", np.array([[origin, origin + fh / draw.NEWTONS_PER_METRE]]),
                    draw.OBSERVER_COLOR, shaft_radius=0.012, head_radius=0.035, head_length=0.07,
                )  # fmt: skip
                self._fhat_shown = True
            elif getattr(self, "_fhat_shown", False):
                scene.add_arrows("/sim/f_hat", np.zeros((1, 2, 3)), (0, 0, 0), visible=False)
                self._fhat_shown = False
        spec = get_spec(snap.robot or self.dashboard.config.robot.model)
        for field, color, opacity, lift in (
            ("adjusted_steps", draw.GHOST_COLOR, 0.25, 0.004),
            ("realised_steps", draw.REALISED_COLOR, 0.6, 0.008),
        ):
            steps = getattr(snap, field)
            if last is not None and _steps_key(steps) == _steps_key(getattr(last, field)):
                continue
            soles = [Sole(s.side, np.asarray(s.position), s.yaw, i) for i, s in enumerate(steps)]
            draw.draw_step_markers(
                scene, f"/sim/{field.removesuffix('_steps')}", soles, spec.foot_length_m,
                spec.foot_width_m, color, opacity=opacity, lift=lift,
            )  # fmt: skip

    def _follow(self, snap: Snapshot) -> None:
        """Move every client's camera by the robot's horizontal displacement since last time."""
        anchor = snap.base_position if snap.base_position is not None else snap.com
        if anchor is None:
            return
        here = np.array([anchor[0], anchor[1], 0.0])
        last, self._follow_anchor = getattr(self, "_follow_anchor", None), here
        if not self.dashboard.gui_follow.value or last is None:
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
        }
        self._com_marker = scene.add_icosphere(
            "/sim/com", radius=0.09, color=(120, 120, 130), visible=False
        )
        # the point mass is clickable like the humanoid: a push at the CoM ("torso")
        self._com_marker.on_click(lambda event: self.dashboard.on_body_click("torso", event))
        self._markers_ready = True

    def _load_robot_view(self, model: str) -> None:
        if self.robot_view is not None:
            self.robot_view.remove()
        self.robot_view = RobotView(self.server, model, on_body_click=self.dashboard.on_body_click)

    def status_text(self, snap: Snapshot) -> str:
        state = "fallen" if snap.fallen else ("walking" if snap.playing else "paused")
        if snap.done and not snap.fallen:
            state = "standing (plan done)"
        speed = (
            f"real-time ×{snap.real_time_factor:4.2f} · {self.fps:4.1f} fps · "
            if snap.playing and not snap.fallen
            else ""
        )
        return (
            f"**{self.dashboard.config.name}** · {snap.robot} · {snap.backend}  \n"
            f"t = {snap.t:6.2f} s · {speed}falls {snap.falls} · {state}"
        )


def _steps_key(steps: tuple) -> tuple:
    return tuple((s.side, round(float(s.position[0]), 4), round(float(s.position[1]), 4))
                 for s in steps)  # fmt: skip
