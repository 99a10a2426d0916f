"""The render thread: draws the simulation loop's latest snapshot into the scene at ≥ 30 fps.

The humanoid (or the point mass), the floor overlays of ξ, ξ_adj and the commanded VRP, the force
arrows, the adjusted (ghost) and realised footsteps, the live DCM plot and the status line.  It
only reads :class:`~dcmviz.dashboard.loop.Snapshot` objects; it never touches the session.  The
walked plan is drawn by :class:`~dcmviz.dashboard.plan_view.PlanView`.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

import numpy as np
import trimesh
import viser

from dcmviz.dashboard import scene as draw
from dcmviz.dashboard.loop import SimLoop, Snapshot
from dcmviz.dashboard.plots import LivePlot
from dcmviz.dashboard.preview import Sole
from dcmviz.dashboard.robot_view import BodyClick, BodyDrag, RobotView
from dcmviz.dashboard.status import StatusLine
from dcmviz.gait.swing import PATH_SAMPLES
from dcmviz.robots import Robot
from dcmviz.session import AppliedPush

RENDER_FPS = 36.0  # scene updates per second (≥ 30 with margin for scheduling jitter; every
# frame costs one message per moving robot mesh and tab)
STATUS_DT_S = 1.0  # the status line is rewritten at most this often, and only if its text changed
PLOT_DT_S = 2.0  # the live plot is redrawn this often (its data is the largest message)
FOLLOW_DT_S = 0.1  # camera-follow updates (per client, so kept slow)
FOLLOW_GROUND_M = 0.02  # the view follows a change of the ground under the robot beyond this
FOLLOW_RECENT = 64  # camera positions remembered per tab (its echoes may come seconds late)
FLOOR_LIFT_M = 0.012  # overlays on the floor sit this high (above the footsteps)
PIN_HEIGHT_M = 0.16  # ξ, ξ_adj and the VRP sit on pins this tall above their ground points:
# on the floor they hid under the feet (the VRP mostly lies under the stance sole)
DOT_RADII_M = (0.03, 0.025, 0.025, 0.02)  # ξ, ξ_adj, commanded VRP atop their pins; the CoP
DOT_COLORS = (draw.MEASURED_DCM_COLOR, draw.ADJUSTED_DCM_COLOR, draw.COMMANDED_VRP_COLOR,
              draw.COP_COLOR)  # fmt: skip
CONTACT_N_PER_M = 1000.0  # contact-force arrows: 1000 N ↔ 1 m (the robot's weight ≈ its height)
MARKER_TOLERANCE_M = 5e-4  # a marker that moved less is not re-sent (below a pixel at 3 m)
ARROW_TOLERANCE_M = 5e-3  # force arrows: ends that moved less are not re-sent
GHOST_MIN_SHIFT_M = 0.01  # an adjusted footstep closer than this to its nominal place is no ghost
STEP_KEY_M = 0.002  # footstep markers are redrawn when a sole moved by this much


def dz_vrp(snap: Snapshot) -> float:
    """Δz_vrp = g b² of the walked plan (m): how far the VRP lies above the floor."""
    return snap.plan.dz_vrp if snap.plan is not None else 0.0


def floor_drop(snap: Snapshot) -> np.ndarray:
    """How far ξ, ξ_adj and the VRP are moved down to lie on the floor (just above the soles):
    they sit about Δz_vrp up, inside the robot, and read better against the footsteps."""
    return np.array([0.0, 0.0, dz_vrp(snap) - FLOOR_LIFT_M])


def pins(points: np.ndarray, ground: float) -> np.ndarray:
    """(n, 2, 3) vertical segments from each point's ground point up PIN_HEIGHT_M."""
    foot = np.array(points, np.float32)
    foot[:, 2] = ground + FLOOR_LIFT_M
    top = foot.copy()
    top[:, 2] += PIN_HEIGHT_M
    return np.stack([foot, top], axis=1)


def contact_arrows(contacts: tuple) -> np.ndarray | None:
    """(n, 2, 3) measured contact forces, each from its centre of pressure (CONTACT_N_PER_M)."""
    if not contacts:
        return None
    return np.array([[p, p + f / CONTACT_N_PER_M] for p, f in contacts], np.float32)


def arrow_points(pushes: tuple[AppliedPush, ...]) -> np.ndarray:
    """(n, 2, 3) arrows of the applied forces, each ending just outside the body it pushes."""
    pts = []
    for push in pushes:
        point, force = push.point, push.force
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
        gui_follow: viser.GuiInputHandle[bool],  # on by default: the robot stays in view
        on_body_click: BodyClick,
        on_follow: Callable[[np.ndarray | None], object] | None = None,
        on_body_drag: BodyDrag | None = None,
        on_frame: Callable[[Snapshot], object] | None = None,
        gui_contacts: viser.GuiInputHandle[bool] | None = None,
    ) -> None:
        self.server = server
        self.loop = loop
        self.live_plot = live_plot
        self.status = status
        self.gui_follow = gui_follow
        self.on_body_click = on_body_click
        self.on_body_drag = on_body_drag
        self.on_frame = on_frame  # each new snapshot drawn (the time panel follows it)
        self.gui_contacts = gui_contacts
        # called at FOLLOW_DT_S with the ground point under the robot (the tabs' aim arrows)
        self.on_follow = on_follow
        self.robot_view: RobotView | None = None
        self.fps = 0.0
        self.frames_drawn = 0
        self.drawn: Snapshot | None = None  # the last snapshot drawn into the scene
        self._drawn_changed = threading.Condition()
        self._markers: dict[str, viser.SceneNodeHandle] = {}
        self._arrow_handles: dict[str, viser.ArrowsHandle] = {}
        self._steps_drawn: dict[str, tuple] = {}  # "adjusted"/"realised" → what is drawn
        self._status_text = ""
        self._follow_anchor: np.ndarray | None = None
        self._cameras: dict[int, tuple] = {}  # per tab: (position and look-at offsets from
        # the robot, positions set)
        self._cameras_lock = threading.Lock()  # the follow's look vs a camera put (put_camera)
        self.faults = 0  # frames that raised (each is reported; drawing goes on)
        self._follow_ground = 0.0  # m, the ground height the view follows
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="dcmviz-render", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)

    def running(self) -> bool:
        return self._thread.is_alive()

    def wait_drawn(self, condition: Callable[[Snapshot], bool], timeout: float) -> bool:
        """Wait until a snapshot for which ``condition`` holds has been drawn into the scene."""
        with self._drawn_changed:
            return self._drawn_changed.wait_for(
                lambda: self.drawn is not None and condition(self.drawn), timeout
            )

    def _run(self) -> None:
        period = 1.0 / RENDER_FPS
        last: Snapshot | None = None
        last_status = 0.0
        last_plot = 0.0
        last_history = None
        last_follow = 0.0
        last_stable = ""  # the status without its clock: written at once when it changes
        frames, fps_t0 = 0, time.perf_counter()
        next_frame = fps_t0
        while not self._stop.is_set():
            t0 = time.perf_counter()
            snap = self.loop.snapshot
            try:
                new = snap is not last
                if new:
                    self.draw_snapshot(snap, last)
                    if (
                        snap.history is not last_history
                        and snap.history
                        and (
                            t0 - last_plot >= PLOT_DT_S
                            or not snap.status.playing
                            or snap.status.frame is not None
                        )
                    ):
                        self.live_plot.draw(snap.history)
                        last_history, last_plot = snap.history, t0
                    last = snap
                    frames += 1
                    self.frames_drawn += 1
                if t0 - fps_t0 >= 1.0:
                    self.fps = frames / (t0 - fps_t0)
                    frames, fps_t0 = 0, t0
                if t0 - last_follow >= FOLLOW_DT_S:
                    here = self._follow(snap)
                    if self.on_follow is not None:
                        self.on_follow(here)
                    last_follow = t0
                stable = self.status.text(snap, self.fps, t0, clock=False)
                if stable != last_stable or t0 - last_status >= STATUS_DT_S:
                    last_stable = stable  # anything but the clock: at once, with the scene
                    self._show_status(snap, t0)
                    last_status = t0
                if new and self.on_frame is not None:
                    self.on_frame(snap)
                if new:  # the scene and the status line show it
                    with self._drawn_changed:
                        self.drawn = snap
                        self._drawn_changed.notify_all()
            except Exception as err:  # noqa: BLE001 - no frame may end the drawing for every tab
                # (seen: viser's message buffer raising "deque mutated during iteration" while
                # a plot was sent); the next frame draws again
                self.faults += 1
                print(f"dcmviz: drawing failed: {err!r}")
            next_frame = max(next_frame + period, time.perf_counter() - period)
            time.sleep(max(0.0, next_frame - time.perf_counter()))

    def _show_status(self, snap: Snapshot, now: float) -> None:
        """Write the status line if its text changed (every tab receives each write)."""
        text = self.status.text(snap, self.fps, now)
        if text != self._status_text:
            self.status.handle.content = text
            self._status_text = text

    def draw_snapshot(self, snap: Snapshot, last: Snapshot | None) -> None:
        """Robot, overlays, force arrows and footstep markers of one snapshot; only what changed
        is sent (every write goes to every tab)."""
        if not self._markers:
            self._make_markers()
        with self.server.atomic():
            self._draw_snapshot(snap)

    def _draw_snapshot(self, snap: Snapshot) -> None:
        self.draw_robot(snap)
        drop = floor_drop(snap)
        tick = snap.tick
        on = self.gui_contacts is None or bool(self.gui_contacts.value)
        if tick is None:
            self._place_dots([None, None, None, None])
            self._segments("pins", None)
        else:
            c = tick.command
            floor = np.array([c.xi, c.xi_adj, c.v_cmd]) - drop  # ground points + FLOOR_LIFT_M
            segments = pins(floor, float(np.min(floor[:, 2])) - FLOOR_LIFT_M)
            cop = tick.cop + [0.0, 0.0, FLOOR_LIFT_M] if tick.cop is not None and on else None
            self._place_dots([*segments[:, 1], cop])
            self._segments("pins", segments)
        self.draw_forces(snap)
        self.draw_contacts(snap)
        self.draw_pull(snap)
        self.draw_swing(snap)
        robot = snap.status.robot
        spec = robot.spec
        realised = tick.realised_steps if tick is not None else ()
        for field, steps, color, opacity, lift in (
            ("adjusted", ghost_steps(snap), draw.GHOST_COLOR, 0.25, 0.004),
            ("realised", realised, draw.REALISED_COLOR, 0.6, 0.008),
        ):
            key = (robot.name, _steps_key(steps))
            if self._steps_drawn.get(field) == key:
                continue
            self._steps_drawn[field] = key
            soles = [Sole(s.side, np.asarray(s.position), s.yaw, i) for i, s in enumerate(steps)]
            draw.draw_step_markers(
                self.server.scene, f"/sim/{field}", soles,
                spec.foot_length_m, spec.foot_width_m, color, opacity=opacity, lift=lift,
            )  # fmt: skip

    def _place_dots(self, positions: list[np.ndarray | None]) -> None:
        """ξ, ξ_adj, the commanded VRP and the CoP: one node of four spheres, so a frame in which
        they moved costs one message, not four (a hidden one is scaled to nothing)."""
        dots = self._markers["dots"]
        scales = np.array([0.0 if p is None else r for p, r in zip(positions, DOT_RADII_M, strict=True)],
                          np.float32)  # fmt: skip
        old = np.asarray(dots.batched_positions)
        new = np.array([old[i] if p is None else p for i, p in enumerate(positions)], np.float32)
        if not np.array_equal(np.asarray(dots.batched_scales), scales):
            dots.batched_scales = scales
        if np.abs(old - new).max() > MARKER_TOLERANCE_M:
            dots.batched_positions = new

    def _place(self, name: str, position: np.ndarray | None) -> None:
        """Show a marker at ``position`` (None hides it), sending only a visible move."""
        handle = self._markers[name]
        handle.visible = position is not None  # viser sends only a change of visibility
        if position is None:
            return
        if np.abs(np.asarray(handle.position) - position).max() > MARKER_TOLERANCE_M:
            handle.position = position

    def draw_robot(self, snap: Snapshot) -> None:
        """The humanoid's meshes, or the point mass (a ball and its pendulum leg)."""
        tick = snap.tick
        pose = snap.pose
        leg = self._markers["lip_leg"]
        if pose is not None:
            robot = snap.status.robot
            if self.robot_view is None or self.robot_view.model != robot.name:
                self._load_robot_view(robot)
            self.robot_view.set_visible(True)
            self.robot_view.update(pose)
            self._place("com", None)
            leg.visible = False  # the point mass's leg leaves with the point mass
            return
        if self.robot_view is not None:
            self.robot_view.set_visible(False)
        self._place("com", snap.com)
        if tick is None and snap.com is None:
            leg.visible = False
            return
        # the pendulum "leg": floor point below the VRP → CoM (at rest, before the first tick of
        # a walk: straight down from the CoM to the ground, where the standing VRP is)
        if tick is not None:
            foot = tick.command.v_cmd - [0.0, 0.0, dz_vrp(snap)]
            com = tick.state.com
        else:
            com = np.asarray(snap.com, float)
            plan = snap.plan
            ground = min(f.position[2] for f in plan.start_feet.values()) if plan else 0.0
            foot = np.array([com[0], com[1], ground])
        points = np.array([[foot, com]], np.float32)
        if np.abs(np.asarray(leg.points) - points).max() > MARKER_TOLERANCE_M:
            leg.points = points
        leg.visible = True

    def draw_forces(self, snap: Snapshot) -> None:
        """Applied forces (at the pushed bodies) and the observer's estimate (above the head)."""
        tick = snap.tick
        pushes = tick.pushes if tick is not None else ()
        self._arrows(
            "/sim/force", arrow_points(pushes) if pushes else None, draw.FORCE_COLOR,
            shaft_radius=0.018, head_radius=0.045, head_length=0.09,
        )  # fmt: skip
        f_hat = None
        if tick is not None and np.linalg.norm(tick.f_hat) > 2.0:
            origin = tick.state.com + [0.0, 0.0, 0.95]
            f_hat = np.array([[origin, origin + tick.f_hat / draw.NEWTONS_PER_METRE]])
        self._arrows(
            "/sim/f_hat", f_hat, draw.OBSERVER_COLOR,
            shaft_radius=0.012, head_radius=0.035, head_length=0.07,
        )  # fmt: skip

    def draw_contacts(self, snap: Snapshot) -> None:
        """The measured contact force of each sole from its centre of pressure (brown arrows;
        the overall centre of pressure is the brown dot), unless switched off."""
        tick = snap.tick
        on = self.gui_contacts is None or bool(self.gui_contacts.value)
        arrows = contact_arrows(tick.contacts) if tick is not None and on else None
        self._arrows(
            "/sim/contacts", arrows, draw.COP_COLOR,
            shaft_radius=0.008, head_radius=0.022, head_length=0.045,
        )  # fmt: skip

    def draw_pull(self, snap: Snapshot) -> None:
        """A drag's spring: a line from where it holds the body to the pointer's point."""
        tick = snap.tick
        pull = tick.pull if tick is not None else None
        point = None
        if pull is not None:
            point = next((p.point for p in tick.pushes if p.body == pull.body), None)
        self._segments(
            "spring", None if point is None else np.array([[pull.grab(point), pull.target]])
        )

    def draw_swing(self, snap: Snapshot) -> None:
        """The swinging sole's path still to go (a crossing step's detour round the stance
        foot included), sent when the path changes: at lift-off and when the recovery moves
        its footstep."""
        tick = snap.tick
        path = tick.swing_path if tick is not None else None
        segments = None if path is None else np.stack([path[:-1], path[1:]], axis=1)
        self._segments("swing", segments, tolerance=0.0)

    def _segments(
        self, name: str, segments: np.ndarray | None, tolerance: float = MARKER_TOLERANCE_M
    ) -> None:
        """Line segments ``name`` ((n, 2, 3) ends; None hides them), their points sent only
        when an end moved more than ``tolerance`` (m) and their visibility only when it
        changes."""
        handle = self._markers[name]
        if segments is None:
            if handle.visible:
                handle.visible = False
            return
        segments = np.asarray(segments, np.float32)
        old = np.asarray(handle.points)
        if old.shape != segments.shape or np.abs(old - segments).max() > tolerance:
            handle.points = segments
        if not handle.visible:
            handle.visible = True

    def _arrows(self, name: str, points: np.ndarray | None, color, **style: float) -> None:
        """Arrows at ``name`` ((n, 2, 3) ends; None hides them), created once per count and then
        moved through the handle only when an end moved visibly."""
        handle = self._arrow_handles.get(name)
        if points is None:
            if handle is not None:
                handle.visible = False
            return
        points = np.asarray(points, np.float32)
        if handle is None or np.asarray(handle.points).shape != points.shape:
            self._arrow_handles[name] = self.server.scene.add_arrows(name, points, color, **style)
            return
        if np.abs(np.asarray(handle.points) - points).max() > ARROW_TOLERANCE_M:
            handle.points = points
        handle.visible = True

    def _follow(self, snap: Snapshot) -> np.ndarray | None:
        """Move every client's camera by the robot's displacement since last time: horizontally
        with the base, vertically with the ground it stands on (the lower supporting sole: it
        changes only when the robot steps up or down terrain, so the view does not bob with the
        gait).  Returns that ground point under the robot (None before there is one)."""
        tick = snap.tick
        pose = snap.pose
        anchor = pose.base_position if pose is not None else snap.com
        if anchor is None:
            return None
        ground = self._follow_ground
        if tick is not None:
            standing = [f[2] for s, f in tick.state.feet.items() if tick.command.support.get(s)]
            ground = float(min(standing)) if standing else ground
        if abs(ground - self._follow_ground) < FOLLOW_GROUND_M:  # the soles' contact jitter
            ground = self._follow_ground
        self._follow_ground = ground
        here = np.array([anchor[0], anchor[1], ground])
        last, self._follow_anchor = self._follow_anchor, here
        if not self.gui_follow.value or last is None:
            return here
        clients = self.server.get_clients()
        with self._cameras_lock:
            for client_id in [c for c in self._cameras if c not in clients]:
                del self._cameras[client_id]  # closed tabs
            for client_id, client in list(clients.items()):
                try:
                    self._follow_camera(client_id, client, here)
                except Exception:  # noqa: BLE001 - a client that just closed
                    pass
        return here

    def _follow_camera(self, client_id: int, client: viser.ClientHandle, here: np.ndarray) -> None:
        """Keep the tab's camera (its position and look-at point) at its offset from the robot.
        The offsets are the ones the tab had when its camera was last put there by someone else
        (the user, Frame robot), taken from the robot where it is now (the camera was put
        looking at the robot drawn lately, not where the last follow left it: one put beside a
        paused robot stays exactly there).  A camera whose reported position is one this method
        set lately is ours, echoed back by a tab that may lag (software rendering: seconds), and
        is not taken for the user's.  Both position and look-at are set: viser moves the look-at
        by the position's change from the last report, which a late echo makes stale."""
        camera = client.camera
        position = np.asarray(camera.position, float)
        entry = self._cameras.get(client_id)
        if entry is None or not any(np.abs(position - p).max() < 1e-3 for p in entry[2]):
            look = np.asarray(camera.look_at, float)
            recent = entry[2] if entry is not None else deque(maxlen=FOLLOW_RECENT)
            entry = (position - here, look - here, recent)  # the user's (or the first) camera
            recent.append(position)  # (known from now on: followed from the next time on)
            self._cameras[client_id] = entry
        offset, look_offset, recent = entry
        target = here + offset
        if np.abs(target - position).max() > 1e-4:
            look_at = here + look_offset
            with client.atomic():
                camera.position = target  # (viser moves the look-at along: right unless stale)
                if np.abs(np.asarray(camera.look_at, float) - look_at).max() > 1e-4:
                    camera.look_at = look_at
            recent.append(target)

    def _make_markers(self) -> None:
        scene = self.server.scene
        sphere = trimesh.creation.icosphere(subdivisions=2)
        self._markers = {
            "dots": scene.add_batched_meshes_simple(
                "/sim/dots",
                sphere.vertices.astype(np.float32),
                sphere.faces.astype(np.uint32),
                batched_wxyzs=np.tile(np.float32([1, 0, 0, 0]), (len(DOT_COLORS), 1)),
                batched_positions=np.zeros((len(DOT_COLORS), 3), np.float32),
                batched_scales=np.zeros(len(DOT_COLORS), np.float32),
                batched_colors=np.array(DOT_COLORS, np.uint8),
                lod="off",
                cast_shadow=False,
                receive_shadow=False,
            ),  # fmt: skip
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
            "pins": scene.add_line_segments(
                "/sim/pins",
                np.zeros((3, 2, 3), np.float32),
                np.array([[c, c] for c in DOT_COLORS[:3]], np.uint8),
                thickness=3.0,
                thickness_units="screen",
                visible=False,
            ),  # fmt: skip
            "swing": scene.add_line_segments(
                "/sim/swing",
                np.zeros((PATH_SAMPLES - 1, 2, 3), np.float32),
                draw.SWING_COLOR,
                thickness=5.0,
                thickness_units="screen",
                visible=False,
            ),  # fmt: skip
            "spring": scene.add_line_segments(
                "/sim/spring",
                np.zeros((1, 2, 3), np.float32),
                (40, 40, 40),
                thickness=3.0,
                thickness_units="screen",
                visible=False,
            ),  # fmt: skip
        }
        # the point mass is clickable like the humanoid: a push at the CoM ("torso")
        self._markers["com"].on_click(lambda event: self.on_body_click("torso", event))
        if self.on_body_drag is not None:

            async def drag(event: viser.SceneNodeDragEvent) -> None:
                self.on_body_drag("torso", event)

            self._markers["com"].on_drag("left")(drag)

    def _load_robot_view(self, robot: Robot) -> None:
        if self.robot_view is not None:
            self.robot_view.remove()
        self.robot_view = RobotView(self.server, robot, self.on_body_click, self.on_body_drag)

    def put_camera(
        self,
        client: viser.ClientHandle,
        position: np.ndarray,
        look_at: np.ndarray,
        up_direction: tuple[float, float, float] | None = None,
    ) -> None:
        """Put a tab's camera at ``position`` looking at ``look_at`` (m, world) and have camera
        follow keep it at that offset from the robot where it is now.  Setting ``client.camera``
        alone races the follow: a late report from a lagging tab (one of the follow's own
        positions) may reach the server after the new camera was set and before the follow
        looks, and the follow then puts the tab back at its old offset."""
        position, look_at = np.asarray(position, float), np.asarray(look_at, float)
        snap = self.loop.snapshot
        anchor = snap.pose.base_position if snap.pose is not None else snap.com
        with self._cameras_lock:
            with client.atomic():  # position first: setting it carries look_at along
                client.camera.position = position
                client.camera.look_at = look_at
                if up_direction is not None:
                    client.camera.up_direction = up_direction
            if anchor is None:
                return
            ground = np.array([anchor[0], anchor[1], self._follow_ground])
            entry = self._cameras.get(client.client_id)
            recent = entry[2] if entry is not None else deque(maxlen=FOLLOW_RECENT)
            recent.append(position)
            self._cameras[client.client_id] = (position - ground, look_at - ground, recent)

    def frame_robot(self, clients: list[viser.ClientHandle] | None = None) -> None:
        """Each tab (or ``clients``) looks at the robot from the first view's angle and
        distance (the "Frame robot" button)."""
        snap = self.loop.snapshot
        pose = snap.pose
        anchor = pose.base_position if pose is not None else snap.com
        if anchor is None:
            return
        ground = self._follow_ground
        look_at = np.array([anchor[0], anchor[1], ground + draw.FRAME_LOOK_AT_HEIGHT_M])
        look_at[:2] += draw.FRAME_SHIFT  # the robot in the middle of the free part of the page
        targets = list(self.server.get_clients().values()) if clients is None else clients
        for client in targets:
            try:
                self.put_camera(client, look_at + draw.FRAME_OFFSET, look_at, (0.0, 0.0, 1.0))
            except Exception:  # noqa: BLE001 - a client that just closed
                pass
        self._follow_anchor = np.array([anchor[0], anchor[1], ground])


def ghost_steps(snap: Snapshot) -> tuple:
    """The adjusted footsteps worth a ghost: the one being adjusted only once it is at least
    GHOST_MIN_SHIFT_M from its place in the walked plan (unpushed, it moves by a hair every
    tick), then those the walked plan moved from the nominal one."""
    tick = snap.tick
    if tick is None:
        return ()
    steps = tick.adjusted_steps()
    if not steps or tick.adjusted_step is None:
        return steps
    planned = np.asarray(tick.plan.steps[tick.adjusted_index].position)
    shift = np.linalg.norm(np.asarray(tick.adjusted_step.position)[:2] - planned[:2])
    return steps if shift >= GHOST_MIN_SHIFT_M else steps[1:]


def _steps_key(steps: tuple) -> tuple:
    """Soles quantised to STEP_KEY_M: equal keys draw the same markers."""
    q = 1.0 / STEP_KEY_M
    return tuple((s.side, round(float(s.position[0]) * q), round(float(s.position[1]) * q),
                  round(float(s.position[2]) * q), round(float(s.yaw) * 500)) for s in steps)  # fmt: skip
