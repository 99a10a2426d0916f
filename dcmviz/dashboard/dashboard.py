"""The dashboard: one viser server, its panels, and the threads that draw.

It only assembles parts; each lives in its own module:

* :class:`~dcmviz.dashboard.loop.SimLoop` owns the session and its clock (the dashboard posts
  commands and reads snapshots);
* :class:`~dcmviz.dashboard.editor.ConfigEditor` is the one place the configuration changes;
* panels: :class:`~dcmviz.dashboard.gui.Controls` (the preset's fields),
  :class:`~dcmviz.dashboard.sim_panel.SimPanel`, :class:`~dcmviz.dashboard.push.PushPanel`,
  :class:`~dcmviz.dashboard.presets.PresetPanel`,
  :class:`~dcmviz.dashboard.recording.RecordingPanel`;
* drawing: :class:`~dcmviz.dashboard.plan_view.PlanView` (the walked plan, when it changes) and
  :class:`~dcmviz.dashboard.render.SimView` (robot, overlays, status, at ≥ 30 fps).

All GUI and scene nodes are server-level, so every browser tab sees the same session; only
notifications and downloads go to the client that asked.
"""

from __future__ import annotations

import asyncio
import math
from collections import deque
from collections.abc import Callable
from pathlib import Path

import viser

from dcmviz import GRAVITY
from dcmviz.config import MAX_PRESET_BYTES, PRESETS_DOC, Config
from dcmviz.dashboard import scene
from dcmviz.dashboard.aim import PushAim
from dcmviz.dashboard.audience import Audience
from dcmviz.dashboard.editor import CURRENT, ConfigEditor
from dcmviz.dashboard.feasibility import FeasibilityPanel, likely_cause
from dcmviz.dashboard.guard import install_guard
from dcmviz.dashboard.gui import Controls
from dcmviz.dashboard.loop import HOLD_MAX_S, SimLoop
from dcmviz.dashboard.notify import Notifier
from dcmviz.dashboard.plan_view import PlanView
from dcmviz.dashboard.plots import LivePlot, PreviewPlots, phase_legend
from dcmviz.dashboard.presets import PresetPanel
from dcmviz.dashboard.push import PushPanel
from dcmviz.dashboard.recording import RecordingPanel
from dcmviz.dashboard.render import SimView
from dcmviz.dashboard.sim_panel import SimPanel
from dcmviz.dashboard.status import StatusLine
from dcmviz.dashboard.terrain_view import TerrainView
from dcmviz.dcm.control import vrp_height
from dcmviz.robots import load_robot
from dcmviz.session import Session

SessionFactory = Callable[[Config], Session]
NEWCOMER_DRAW_TIMEOUT_S = 2.0  # a new tab's connection waits at most this for the restarted walk


def new_session(config: Config) -> Session:
    return Session(config, backend=config.sim.backend)


def dz_vrp_text(config: Config) -> str:
    """Markdown: Δz_vrp = g b² of the configured b (eq. 1) and the CoM heights the robot walks at."""
    b = config.dcm.b
    spec = load_robot(config.robot.model).spec
    lo, hi = spec.com_height_range_m
    b_lo, b_hi = spec.b_range_s
    b_lo, b_hi = math.ceil(b_lo * 1000) / 1000, math.floor(b_hi * 1000) / 1000  # the slider's
    return (
        f"Δz_vrp = g b² = {GRAVITY:.2f} · {b:.3f}² = **{vrp_height(b):.3f} m**; "
        f"{spec.name.capitalize()} walks at {lo:.2f}–{hi:.2f} m (b {b_lo:.3f}–{b_hi:.3f} s)"
    )


class Dashboard:
    """The dcmviz dashboard on one viser server."""

    def __init__(
        self,
        server: viser.ViserServer,
        config: Config,
        *,
        presets_dir: Path | str = "presets",
        start: bool = True,
        session_factory: SessionFactory = new_session,
        preset: str = CURRENT,
        key: str | None = None,
        max_tabs: int = 50,
        audience_push: bool = False,
    ) -> None:
        self.server = server
        self.notifier = Notifier(server)
        # presenter and watchers: in front of the guard (a watcher's message never reaches it)
        self.audience = Audience(
            server, key, max_tabs=max_tabs, audience_push=audience_push,
            notify=self.notifier.notify_client_id,
        )  # fmt: skip
        install_guard(
            server, notify=self.notifier.notify_client_id, max_upload_bytes=MAX_PRESET_BYTES,
            upload_doc=PRESETS_DOC,
        )  # fmt: skip
        self.loop = SimLoop(session_factory, config, on_event=self._on_sim_event)
        self.editor = ConfigEditor(config, self.loop, self.notifier)
        scene.draw_ground(server)
        self.terrain_view = TerrainView(server.scene)  # stairs and boxes of the preset
        self.editor.on_applied(lambda config, preset: self.terrain_view.show(config))

        gui = server.gui
        gui.configure_theme(
            control_width="large", show_share_button=False, brand_color=(30, 60, 200)
        )
        self.gui_status = gui.add_markdown("**dcmviz** starting…")
        tabs = gui.add_tab_group()
        with tabs.add_tab("Plan", viser.Icon.SHOE):
            self.gui_push_hint = gui.add_markdown("")  # push without hunting (the Simulate tab)
            self.feasibility = FeasibilityPanel(gui)
            self.controls = Controls(gui, config)
        with tabs.add_tab("Simulate", viser.Icon.PLAYER_PLAY):
            self.sim_panel = SimPanel(gui, self.loop, self.controls, config)
            gui.add_markdown(scene.SCENE_LEGEND)
            self.push_panel = PushPanel(gui, self.loop, self.editor, self.notifier)
        # each tab's arrow: the force a click on the robot applies from that tab's view
        self.aim = PushAim(server, self.push_panel.click_force)
        self.push_panel.aim = self.aim
        self.push_panel.who = self.audience.label
        self.push_panel.on_hint(lambda _hint: self.aim.refresh())
        with tabs.add_tab("Presets", viser.Icon.FILE_SETTINGS):
            self.preset_panel = PresetPanel(gui, self.editor, self.notifier, presets_dir, preset)
            self.recording = RecordingPanel(gui, self.loop, self.notifier, self.config_name)
        with tabs.add_tab("Sweep", viser.Icon.CHART_DOTS):
            from dcmviz.dashboard.sweep_panel import SweepPanel  # (Ray loads on Start only)

            self.sweep_panel = SweepPanel(gui, lambda: self.editor.config, self.notifier)
        self.plot_panel = gui.add_panel()  # docked left: Fig. 1a and the live DCM
        with self.plot_panel.add_tab("Preview (Fig. 1a)", viser.Icon.CHART_LINE):
            gui.add_markdown(phase_legend())
            self.preview_plots = PreviewPlots(gui)
        with self.plot_panel.add_tab("Live DCM", viser.Icon.ACTIVITY):
            self.gui_live_axis = gui.add_dropdown("axis", ("x", "y", "z"), initial_value="y")
            self.live_plot = LivePlot(gui, "y")
            self.gui_live_axis.on_update(lambda event: self.live_plot.set_axis(event.target.value))
        self.plot_panel.dock_left()
        self.plot_panel.set_width(400)

        self.preview = PlanView(
            server, self.loop, self.preview_plots, self.controls.extra["gizmos"],
            self.notifier.guarded("dragging a footstep", self.editor.on_footstep_moved),
            config=lambda: self.editor.config,
            on_warnings=lambda warnings: self.feasibility.show(
                warnings, "the walked plan", self.loop.snapshot.status.version, walked=True
            ),
        )  # fmt: skip
        self.view = SimView(
            server, self.loop, live_plot=self.live_plot,
            status=StatusLine(self.gui_status, self.config_name, extra=self.status_extra),
            gui_follow=self.sim_panel.gui_follow,
            on_body_click=self.notifier.guarded("click-to-push", self.push_panel.on_body_click),
            on_follow=self.aim.follow,
        )  # fmt: skip
        self._wire()
        self.show_config(config, preset)
        self.terrain_view.show(config)
        self.preview.update(self.loop.snapshot)  # the walk's plan, before any thread runs
        if start:
            self.start()

    def _wire(self) -> None:
        """Controls → editor → (panels, plan view); refusals put the controls back."""
        self.controls.on_change(self.notifier.guarded("a control", self.editor.on_field_change))
        self.controls.extra["reset_footsteps"].on_click(
            self.notifier.guarded(
                "regenerate footsteps",
                lambda event: self.editor.on_regenerate_footsteps(event.client),
            )
        )
        self.editor.on_applied(
            lambda config, preset: self.feasibility.show(
                self.editor.warnings, "this edit", self.editor.version, walked=False
            )
        )
        self.push_panel.on_hint(self.show_push_hint)
        self.show_push_hint(self.push_panel.hint())
        self.server.on_client_connect(self._on_connect)
        # viser's websocket layer calls these before it replays the scene to a new connection
        # (ViserServer.on_client_connect fires only later, at the tab's first camera message)
        websocket = getattr(self.server, "_websock_server", None)
        self._early_connect = websocket is not None
        if websocket is not None:
            websocket.on_client_connect(self._on_websocket_open)
        self.editor.on_applied(self.show_config)
        self.editor.on_applied(lambda config, preset: self.preview.expect(self.editor.version))
        self.editor.on_rejected(self.controls.show)
        self.editor.on_rejected(lambda config: self.preview.draw_gizmos())

    def show_config(self, config: Config, preset: str) -> None:
        """The Plan tab shows an adopted config (the other panels listen to the editor)."""
        self.controls.show(config)
        self.controls.extra["dz_vrp"].content = dz_vrp_text(config)

    def show_push_hint(self, hint: str) -> None:
        self.gui_push_hint.content = f"<small>**Push:** {hint}</small>"

    def status_extra(self) -> str:
        """Status lines after the walk state: the plan's feasibility, what a click pushes."""
        warn = self.feasibility.compact()
        return "  \n".join(x for x in (warn, self.push_panel.status()) if x)

    def _first_viewer(self) -> bool:
        """Nobody watches (no tab has reported its camera) and the walk is a plan, running."""
        return (
            not self.server.get_clients()
            and self.config.gait.mode == "plan"
            and self.loop.running()
        )

    async def _on_websocket_open(self, _connection: object) -> None:
        """A tab opened its connection, before viser replays the scene to it.  The first viewer
        sees the walk from its start, not a walk that ended before the page opened: the walk
        restarts and holds at its start, and the restarted robot is drawn into the scene
        before the replay, so the tab's first picture is the robot standing where the walk
        begins (no stale pose, no jump back when the reset arrives).  The hold ends when the
        tab reports its camera (its 3-D view is up), at most HOLD_MAX_S later."""
        if not self._first_viewer():
            return
        await asyncio.get_running_loop().run_in_executor(None, self._restart_for_newcomer)

    def _restart_for_newcomer(self) -> None:
        resets = self.loop.resets
        self.loop.post("reset")
        self.loop.post("hold", HOLD_MAX_S)
        if self.view.running():
            self.view.wait_drawn(lambda snap: snap.status.resets > resets, NEWCOMER_DRAW_TIMEOUT_S)

    def _on_connect(self, client: viser.ClientHandle) -> None:
        """A tab reported its camera (its view is up): a walk held for it starts."""
        if self.loop.held:
            self.loop.post("hold", 0.0)
        elif not self._early_connect and len(self.server.get_clients()) <= 1:
            if self.config.gait.mode == "plan":  # (no early hook: restart, visibly)
                self.loop.post("reset")

    def _on_sim_event(self, kind: str, message: str) -> None:
        """A fall or fault (on the simulation thread): shown once, with its likely cause."""
        try:
            session = self.loop.session
            pushed = any(p.start - 0.1 <= session.t <= p.start + p.duration + 1.5
                         for p in session.pushes)  # fmt: skip
            cause = likely_cause(self.feasibility.warnings, self.editor.config, pushed)
        except Exception as err:  # noqa: BLE001 - explaining must not fail the report
            cause = f"cause unknown ({err!r})"
        self.notifier.on_sim_event(kind, f"{message} {cause[0].upper()}{cause[1:]}.")

    # -- what tests, benchmarks and the status line read -----------------------------------------
    @property
    def config(self) -> Config:
        """The last good configuration."""
        return self.editor.config

    @property
    def version(self) -> int:
        """Counts adopted configurations."""
        return self.editor.version

    @property
    def notifications(self) -> deque[tuple[str, str]]:
        return self.notifier.notifications

    def config_name(self) -> str:
        return self.editor.config.name

    # -- lifecycle ------------------------------------------------------------------------------
    def start(self) -> None:
        self.loop.start()
        self.preview.start()
        self.view.start()

    def stop(self) -> None:
        self.view.stop()
        self.preview.stop()
        self.loop.stop()
        self.audience.close()


def serve(
    config: Config,
    *,
    host: str = "127.0.0.1",
    port: int = 8080,
    presets_dir: Path | str = "presets",
    preset: str = CURRENT,
    key: str | None = None,
    max_tabs: int = 50,
    audience_push: bool = False,
) -> tuple[viser.ViserServer, Dashboard]:
    """A viser server on ``host:port`` with the dashboard running ``config`` (from ``preset``);
    with a ``key``, only tabs that connect with it control (:mod:`.audience`)."""
    server = viser.ViserServer(host=host, port=port, label="dcmviz", verbose=False)
    try:
        dashboard = Dashboard(
            server, config, presets_dir=presets_dir, preset=preset, key=key,
            max_tabs=max_tabs, audience_push=audience_push,
        )  # fmt: skip
    except BaseException:
        server.stop()
        raise
    return server, dashboard
