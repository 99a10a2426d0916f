"""The plan the walker walks, drawn: footsteps, VRP/DCM preview in 3-D, Fig. 1a plots, gizmos.

It reads the simulation loop's snapshots (the walked plan starts from the measured feet and CoM)
and redraws whenever ``plan_version`` changes: a new config, a reset, a touchdown that commits an
adjusted footstep, the receding horizon of continuous mode.  It never builds a plan itself.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

import numpy as np
import viser

from dcmviz.config import Config
from dcmviz.dashboard import scene as draw
from dcmviz.dashboard.feasibility import plan_warnings
from dcmviz.dashboard.loop import SimLoop, Snapshot
from dcmviz.dashboard.plots import PreviewPlots
from dcmviz.dashboard.preview import PreviewData, preview_data
from dcmviz.gait import GaitPlan, PlanWarning
from dcmviz.robots import Robot

POLL_S = 0.004  # how often the drawing thread looks for a new plan (cheap: one comparison)
KEPT_LATENCIES = 200

FootstepMoved = Callable[[int, np.ndarray, viser.ClientHandle | None], bool]
Warned = Callable[[tuple[PlanWarning, ...]], None]


class PlanView:
    """Draws the walked plan in its own thread; :meth:`wait` blocks until a config is shown."""

    def __init__(
        self,
        server: viser.ViserServer,
        loop: SimLoop,
        plots: PreviewPlots,
        gui_gizmos: viser.GuiInputHandle[bool],
        on_footstep_moved: FootstepMoved,
        *,
        config: Callable[[], Config] | None = None,
        on_warnings: Warned | None = None,
    ) -> None:
        self.server = server
        self.config = config  # the settings the walked plan came from (names in the warnings)
        self.on_warnings = on_warnings
        self.warnings: tuple[PlanWarning, ...] = ()  # of the drawn plan
        self.loop = loop
        self.plots = plots
        self.gui_gizmos = gui_gizmos
        self.on_footstep_moved = on_footstep_moved
        self.plan: GaitPlan | None = None  # the plan drawn
        self.data: PreviewData | None = None  # its samples
        self.kept: PreviewData | None = None  # the preview kept to compare against (A)
        self._checked: GaitPlan | None = None  # the nominal plan the warnings are of
        self.drawn_plan_version = -1
        self.drawn_version = -1  # newest config version whose walk is drawn
        self.draws = 0
        self.latency_s: dict[int, float] = {}  # config version → expect() to drawn, s
        self.cpu_s: dict[int, float] = {}  # config version → CPU s of the drawing thread
        self._expected: deque[tuple[int, float]] = deque(maxlen=KEPT_LATENCIES)
        self._cond = threading.Condition()
        self._draw_lock = threading.RLock()
        self._gizmos: list[viser.TransformControlsHandle] = []
        self._gizmo_quiet = threading.local()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="dcmviz-plan", daemon=True)
        gui_gizmos.on_update(lambda _: self.draw_gizmos())

    # -- thread ---------------------------------------------------------------------------------
    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)

    def _run(self) -> None:
        while not self._stop.wait(POLL_S):
            try:
                self.update(self.loop.snapshot)
            except Exception as err:  # noqa: BLE001 - a drawing bug must not stop the thread
                print(f"dcmviz: plan drawing failed: {err!r}")

    def expect(self, version: int) -> None:
        """Config ``version`` was just submitted: measure how long until its walk is drawn."""
        with self._cond:
            self._expected.append((version, time.perf_counter()))

    def update(self, snap: Snapshot) -> bool:
        """Draw the snapshot's plan if it is not the one drawn; True if it drew."""
        drew = False
        cpu0 = time.thread_time()
        if snap.plan is not None and snap.plan_version != self.drawn_plan_version:
            self.draw_plan(snap.plan, snap.status.robot, snap.nominal_plan)
            self.drawn_plan_version = snap.plan_version
            drew = True
        if snap.status.version > self.drawn_version or drew:
            now, cpu = time.perf_counter(), time.thread_time() - cpu0
            with self._cond:
                self.drawn_version = max(self.drawn_version, snap.status.version)
                while self._expected and self._expected[0][0] <= self.drawn_version:
                    version, t_submit = self._expected.popleft()
                    self.latency_s[version] = now - t_submit
                    self.cpu_s[version] = cpu
                for old in list(self.latency_s)[:-KEPT_LATENCIES]:
                    self.latency_s.pop(old, None)
                    self.cpu_s.pop(old, None)
                self._cond.notify_all()
        return drew

    def wait(self, version: int, timeout: float = 5.0) -> bool:
        """Block until the walk of config ``version`` (or a newer one) is drawn."""
        deadline = time.perf_counter() + timeout
        with self._cond:
            while self.drawn_version < version:
                left = deadline - time.perf_counter()
                if left <= 0:
                    return False
                self._cond.wait(left)
        return True

    # -- drawing --------------------------------------------------------------------------------
    def draw_plan(
        self, plan: GaitPlan, robot: Robot, nominal: GaitPlan | None = None
    ) -> PreviewData:
        """Sample the plan and redraw the 3-D preview, the gizmos and the Fig. 1a plots.

        The feasibility warnings are those of the ``nominal`` plan (the settings' plan, default
        ``plan``), checked once per nominal plan: a footstep that step adjustment moved is the
        recovery's doing, not a setting to blame (and would change the count at every landing)."""
        data = preview_data(plan, robot.spec)
        with self._draw_lock:  # Fig. 1a first: its frame need not wait for the 3-D scene's update
            self.plots.draw(data)
        nominal = plan if nominal is None else nominal
        if nominal is self._checked:
            warnings = self.warnings
        else:
            warnings = plan_warnings(nominal, self.config()) if self.config is not None else ()
            self._checked = nominal
        steps = {w.step for w in warnings if w.step is not None}
        waypoints = sorted({w.waypoint for w in warnings if w.waypoint is not None})
        with self._draw_lock:
            with self.server.atomic():
                draw.draw_footsteps(self.server.scene, data)
                draw.draw_preview(self.server.scene, data)
                draw.draw_warnings(
                    self.server.scene, [s for s in data.soles if s.index in steps],
                    data.waypoints[[w for w in waypoints if w < len(data.waypoints)]],
                    data.foot_length, data.foot_width,
                )  # fmt: skip
            self.plan, self.data, self.warnings = plan, data, warnings
            if self.on_warnings is not None:
                self.on_warnings(warnings)
            self.draws += 1
            self.draw_gizmos()
        return data

    def keep(self) -> PreviewData | None:
        """Keep the preview drawn now as A: it stays drawn (grey, in 3-D and in the Fig. 1a
        plots) to compare the next settings against."""
        with self._draw_lock:
            self.kept = self.data
            draw.draw_kept(self.server.scene, self.kept)
            self.plots.set_ghost(self.kept)
        return self.kept

    def clear_kept(self) -> None:
        with self._draw_lock:
            self.kept = None
            draw.draw_kept(self.server.scene, None)
            self.plots.set_ghost(None)

    def draw_gizmos(self) -> None:
        """One translation gizmo per footstep of the drawn plan (xy plane) when enabled."""
        with self._draw_lock:
            steps = self.plan.steps if self.plan is not None and self.gui_gizmos.value else ()
            positions = [np.asarray(s.position, float) + [0.0, 0.0, 0.01] for s in steps]
            while len(self._gizmos) > len(positions):
                self._gizmos.pop().remove()
            for i, pos in enumerate(positions):
                if i < len(self._gizmos):
                    self._move_gizmo(self._gizmos[i], pos)
                    continue
                gizmo = self.server.scene.add_transform_controls(
                    f"/gizmos/step_{i}", scale=0.18, line_width=2.0,
                    active_axes=(True, True, False), disable_rotations=True,
                    disable_sliders=False, depth_test=False, position=pos,
                )  # fmt: skip
                gizmo.on_update(self._gizmo_callback(i))
                self._gizmos.append(gizmo)

    def _move_gizmo(self, gizmo: viser.TransformControlsHandle, pos: np.ndarray) -> None:
        if np.linalg.norm(np.asarray(gizmo.position) - pos) <= 1e-6:
            return
        self._gizmo_quiet.on = True  # a move by the server, not a drag
        try:
            gizmo.position = pos
        finally:
            self._gizmo_quiet.on = False

    def _gizmo_callback(self, index: int) -> Callable[[viser.TransformControlsEvent], None]:
        def moved(event: viser.TransformControlsEvent) -> None:
            if getattr(self._gizmo_quiet, "on", False):
                return
            self.on_footstep_moved(index, np.asarray(event.target.position), event.client)

        return moved
