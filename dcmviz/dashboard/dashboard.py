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
  :class:`~dcmviz.dashboard.render.SimView` (robot, overlays, status, at ≥ 30 fps);
* time: :class:`~dcmviz.dashboard.time_panel.TimePanel` (pause, steps, scrubbing the loop's
  buffer, resuming from a frame).

All GUI and scene nodes are server-level, so every browser tab sees the same session; only
notifications and downloads go to the client that asked.
"""

from __future__ import annotations

import asyncio
import math
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path

import numpy as np
import viser

from dcmviz import GRAVITY
from dcmviz.config import MAX_PRESET_BYTES, PRESETS_DOC, Config
from dcmviz.dashboard import scene
from dcmviz.dashboard.aim import PushAim
from dcmviz.dashboard.audience import Audience
from dcmviz.dashboard.editor import CURRENT, ConfigEditor
from dcmviz.dashboard.feasibility import FeasibilityPanel, likely_cause, setting_to_change
from dcmviz.dashboard.fig1a import FIG1A_MODES, FigureStream, PreviewFigure, next_free_port
from dcmviz.dashboard.guard import install_guard
from dcmviz.dashboard.gui import Controls
from dcmviz.dashboard.heap import fix_mmap_threshold
from dcmviz.dashboard.loop import HOLD_MAX_S, SimLoop
from dcmviz.dashboard.notify import Notifier
from dcmviz.dashboard.plan_view import PlanView
from dcmviz.dashboard.plots import LivePlot, PreviewPlots, live_controls, phase_legend
from dcmviz.dashboard.presets import PresetPanel
from dcmviz.dashboard.push import PushPanel
from dcmviz.dashboard.ranges import DEPENDENT, valid_range
from dcmviz.dashboard.recording import RecordingPanel
from dcmviz.dashboard.render import SimView
from dcmviz.dashboard.sim_panel import SimPanel
from dcmviz.dashboard.status import StatusLine
from dcmviz.dashboard.terrain_view import TerrainView
from dcmviz.dashboard.time_panel import TimePanel
from dcmviz.dcm.control import vrp_height
from dcmviz.robots import load_robot
from dcmviz.session import Session

SessionFactory = Callable[[Config], Session]
NEWCOMER_DRAW_TIMEOUT_S = 2.0  # a new tab's connection waits at most this for the restarted walk
RELOAD_GRACE_S = 30.0  # a tab that opens this soon after the last one closed is a reload: the
# walk it finds (paused, scrubbed, pushed, recorded) is kept, never restarted for it


def new_session(config: Config) -> Session:
    return Session(config, backend=config.sim.backend)


def dz_vrp_text(config: Config) -> str:
    """Markdown: Δz_vrp = g b² of the configured b (eq. 1) and the CoM heights the robot walks at."""
    b = config.dcm.b
    spec = load_robot(config.robot.model).spec
    lo, hi = spec.com_height_range_m
    b_lo, b_hi = spec.b_range_text()  # the slider's ends: every b between them is accepted
    return (
        f"Δz_vrp = g b² = {GRAVITY:.2f} · {b:.3f}² = **{vrp_height(b):.3f} m**; "
        f"{spec.name.capitalize()} walks at {lo:.2f}–{hi:.2f} m (b {b_lo}–{b_hi} s; longer "
        "steps may lower the CoM: a warning says so)"
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
        fig1a: str = "stream",
        fig1a_port: int = 0,
    ) -> None:
        if fig1a not in FIG1A_MODES:
            raise ValueError(f"fig1a: {fig1a!r} is not one of {', '.join(FIG1A_MODES)}")
        self.fig1a_stream: FigureStream | None = None
        try:
            self._build(server, config, presets_dir, session_factory, preset, key, max_tabs,
                        audience_push, fig1a, fig1a_port)  # fmt: skip
            if start:
                self.start()
        except BaseException:
            self._abandon()
            raise

    def _abandon(self) -> None:
        """After a construction that raised: stop what was started (the threads, Fig. 1a's
        port, the key's log filter); the caller owns the server."""
        if hasattr(self, "_ranges_thread"):
            self.stop()
            return
        if self.fig1a_stream is not None:
            self.fig1a_stream.stop()
        if hasattr(self, "audience"):
            self.audience.close()

    def _build(self, server, config, presets_dir, session_factory, preset, key, max_tabs,
               audience_push, fig1a, fig1a_port) -> None:  # fmt: skip
        """The panels, the loop and the views (:meth:`__init__`'s arguments), nothing started."""
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
        self.ground = scene.draw_ground(server)
        self.terrain_view = TerrainView(server.scene)  # stairs and boxes of the preset
        self.editor.on_applied(lambda config, preset: self.terrain_view.show(config))

        gui = server.gui
        gui.configure_theme(
            control_width="large", show_share_button=False, brand_color=(30, 60, 200)
        )
        self.gui_status = gui.add_markdown("**dcmviz** starting…")
        self.gui_legend = gui.add_markdown(scene.SCENE_LEGEND)  # always in sight
        self.time_panel = TimePanel(gui, self.loop)
        with gui.add_folder("View"):
            self.gui_frame = gui.add_button(
                "Frame robot", icon=viser.Icon.FOCUS_CENTERED,
                hint="Look at the robot from the first view's angle (this tab)",
            )  # fmt: skip
            self.gui_follow = gui.add_checkbox(
                "Camera follows the robot", initial_value=True,
                hint="Every open view keeps its angle and moves with the robot",
            )  # fmt: skip
            self.gui_contacts = gui.add_checkbox(
                "CoP and contact forces", initial_value=True,
                hint="The measured centre of pressure (brown disc) and each sole's contact force",
            )  # fmt: skip
        tabs = gui.add_tab_group()
        with tabs.add_tab("Plan", viser.Icon.SHOE):
            self.gui_push_hint = gui.add_markdown("")  # push without hunting (the Simulate tab)
            with gui.add_folder("Compare (A/B)", expand_by_default=False):
                self.gui_keep = gui.add_button(
                    "Keep this preview as A", icon=viser.Icon.PIN,
                    hint="The preview drawn now stays drawn in grey (3-D and Fig. 1a) to "
                    "compare the next settings (B) against",
                )  # fmt: skip
                self.gui_clear_kept = gui.add_button("Clear A", disabled=True)
                self.gui_kept = gui.add_markdown("<small>no preview kept</small>")
            self.feasibility = FeasibilityPanel(gui)
            self.controls = Controls(gui, config)
        with tabs.add_tab("Simulate", viser.Icon.PLAYER_PLAY):
            self.sim_panel = SimPanel(gui, self.loop, self.controls, config, self.time_panel)
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
        self.plot_panel = gui.add_panel()  # docked left: Fig. 1a and the live signals
        with self.plot_panel.add_tab("Preview (Fig. 1a)", viser.Icon.CHART_LINE):
            gui.add_markdown(phase_legend())
            if fig1a == "stream":
                self.fig1a_stream = FigureStream(
                    server.get_host(), fig1a_port, max_streams=max_tabs + 8
                )  # (+ the presenter's tabs)
                self.preview_plots: PreviewFigure | PreviewPlots = PreviewFigure(
                    gui, self.fig1a_stream
                )
            else:
                self.preview_plots = PreviewPlots(gui)
        with self.plot_panel.add_tab("Live", viser.Icon.ACTIVITY):
            self.live_plot = LivePlot(gui, "y")
            self.live_handles = live_controls(
                gui, self.live_plot, lambda s: self.loop.post("plot_window", s)
            )
        self.gui_live_axis = self.live_handles["axis"]
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
        self.fall_advice = ""  # after repeated falls: the setting to change (status line)
        self._last_refresh = 0.0
        self.view = SimView(
            server, self.loop, live_plot=self.live_plot,
            status=StatusLine(self.gui_status, self.config_name, extra=self.status_extra),
            gui_follow=self.gui_follow,
            on_body_click=self.notifier.guarded("click-to-push", self.push_panel.on_body_click),
            on_follow=self._followed,
            on_body_drag=self.notifier.guarded("drag-to-push", self.push_panel.on_body_drag),
            on_frame=self._on_frame,
            gui_contacts=self.gui_contacts,
        )  # fmt: skip
        self._ranges_wanted = threading.Event()
        self._ranges_stop = threading.Event()
        self._ranges_thread = threading.Thread(
            target=self._keep_ranges, name="dcmviz-ranges", daemon=True
        )
        self._last_client_seen = -math.inf  # monotonic time a tab was last connected
        self._wire()
        self.show_config(config, preset)
        self.terrain_view.show(config)
        self.preview.update(self.loop.snapshot)  # the walk's plan, before any thread runs

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
        self.editor.on_applied(lambda config, preset: self._ranges_wanted.set())
        self.server.on_client_disconnect(self._on_disconnect)
        self.gui_frame.on_click(
            lambda event: self.view.frame_robot([event.client] if event.client else None)
        )
        self.gui_keep.on_click(self.notifier.guarded("Keep preview", lambda e: self.on_keep()))
        self.gui_clear_kept.on_click(lambda e: self.on_clear_kept())

    def show_config(self, config: Config, preset: str) -> None:
        """The Plan tab shows an adopted config (the other panels listen to the editor)."""
        self.controls.show(config)
        self.controls.extra["dz_vrp"].content = dz_vrp_text(config)

    def on_keep(self) -> None:
        """Keep the preview drawn now as A (grey in 3-D and in Fig. 1a)."""
        kept = self.preview.keep()
        if kept is None:
            return
        self.gui_clear_kept.disabled = False
        st = self.loop.snapshot.status
        self.gui_kept.content = (
            f"<small>A: the preview at t = {st.t:.2f} s ({self.config.name}; k_ξ = "
            f"{self.config.control.k_xi:g}, b = {self.config.dcm.b:g} s); grey in 3-D and in "
            "Fig. 1a</small>"
        )

    def on_clear_kept(self) -> None:
        self.preview.clear_kept()
        self.gui_clear_kept.disabled = True
        self.gui_kept.content = "<small>no preview kept</small>"

    def _keep_ranges(self) -> None:
        """The sliders whose valid range depends on other settings follow every adopted edit
        (:mod:`dcmviz.dashboard.ranges`; in this thread: a few dozen validations)."""
        while not self._ranges_stop.is_set():
            if not self._ranges_wanted.wait(0.5):
                continue
            self._ranges_wanted.clear()
            try:
                self.apply_ranges()
            except Exception as err:  # noqa: BLE001 - ranges must not stop anything
                print(f"dcmviz: slider ranges failed: {err!r}")

    def apply_ranges(self) -> dict[tuple[str, str], tuple[float, float]]:
        """Set the dependent sliders' ranges to what validation accepts now; returns them."""
        config = self.editor.config
        ranges = {}
        for section, name in DEPENDENT:
            if (section, name) not in self.controls.handles:
                continue
            lo, hi, step = self.controls.static_range(section, name)
            ranges[(section, name)] = valid_range(config, section, name, lo, hi, step)
        if config is self.editor.config:  # not overtaken by a newer edit
            self.controls.apply_ranges(ranges)
        return ranges

    def _on_frame(self, snap) -> None:
        """Each drawn snapshot: the Time folder follows it; once a second the recording's line."""
        self.time_panel.show(snap)
        now = time.monotonic()
        if now - self._last_refresh >= 1.0:
            self._last_refresh = now
            self.recording.refresh()

    def show_push_hint(self, hint: str) -> None:
        self.gui_push_hint.content = f"<small>**Push:** {hint}</small>"

    def status_extra(self, snap) -> str:
        """Status lines after the walk state: advice after repeated falls, the plan's
        feasibility, what a click pushed or a drag pulls."""
        warn = self.feasibility.compact()
        pulling = ""
        tick = snap.tick
        if tick is not None and tick.pull is not None:
            force = next((p.force for p in tick.pushes if p.body == tick.pull.body), None)
            if force is not None:
                pulling = f"pulling {tick.pull.body}: {float(np.linalg.norm(force)):.0f} N"
        advice = (
            self.fall_advice
            if snap.status.paused_reason.startswith("paused after")
            and "falls" in snap.status.paused_reason
            else ""
        )
        return "  \n".join(x for x in (advice, warn, self.push_panel.status(pulling)) if x)

    def _first_viewer(self) -> bool:
        """Nobody watches (no tab has reported its camera), nobody did in the last
        RELOAD_GRACE_S (a reload keeps what it finds), and the walk is a plan running unpaused
        at its live end with nothing being recorded."""
        return (
            not self.server.get_clients()
            and time.monotonic() - self._last_client_seen > RELOAD_GRACE_S
            and self.config.gait.mode == "plan"
            and self.loop.running()
            and self.loop.playing
            and self.loop.cursor is None
            and self.recording.recorder is None
        )

    def _on_disconnect(self, client: viser.ClientHandle) -> None:
        self._last_client_seen = time.monotonic()

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
        self._last_client_seen = time.monotonic()
        if self.loop.held:
            self.loop.post("hold", 0.0)
        elif not self._early_connect and len(self.server.get_clients()) <= 1:
            if self.config.gait.mode == "plan" and self.loop.playing:  # (no early hook)
                self.loop.post("reset")

    def _followed(self, point: np.ndarray | None) -> None:
        """The ground point under the robot (render thread): the aim arrows and the floor grid
        follow it."""
        self.aim.follow(point)
        self.ground.follow(point)

    def _on_sim_event(self, kind: str, message: str) -> None:
        """A fall, a fault or a resume (on the simulation thread): a fall is shown once with
        its likely cause (a push just before it first); after FALLS_BEFORE_PAUSE falls in a row
        on one setting the walk pauses and the status names the setting to change."""
        if kind == "resumed":
            self._adopt_walked()
            return
        advice = ""
        try:
            fall = self.loop.last_fall if kind == "fell" else None
            push = fall.push if fall is not None else None
            cause = likely_cause(self.feasibility.warnings, self.editor.config, push)
            if fall is not None and fall.paused:
                setting = setting_to_change(self.feasibility.warnings, self.editor.config)
                advice = (
                    f"<span style='color:#e61414'>**{fall.streak} falls in a row with these "
                    f"settings: the walk is paused. Change {setting}**</span>, then press Play"
                )
                self.fall_advice = advice
        except Exception as err:  # noqa: BLE001 - explaining must not fail the report
            cause = f"cause unknown ({err!r})"
        text = f"{message} {cause[0].upper()}{cause[1:]}."
        if advice:
            text += f" Paused after {fall.streak} falls in a row: change {setting}."
        self.notifier.on_sim_event(kind, text)

    def _adopt_walked(self) -> None:
        """After "resume from here": the walk goes on with its own settings (and the gains set
        now); the panel shows them (edits of other settings since that frame are undone)."""
        walked = self.loop.session.config
        if walked != self.editor.config:
            self.editor.apply_config(walked)

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
        self._ranges_thread.start()
        self._ranges_wanted.set()

    def stop(self) -> None:
        self._ranges_stop.set()
        if self._ranges_thread.is_alive():
            self._ranges_thread.join(timeout=5.0)
        self.view.stop()
        self.preview.stop()
        self.loop.stop()
        self.audience.close()
        if self.fig1a_stream is not None:
            self.fig1a_stream.stop()


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
    fig1a: str = "stream",
) -> tuple[viser.ViserServer, Dashboard]:
    """A viser server on ``host:port`` with the dashboard running ``config`` (from ``preset``);
    with a ``key``, only tabs that connect with it control (:mod:`.audience`).  ``fig1a``:
    "stream" draws Fig. 1a in a frame of its own fed from the next free port after the
    dashboard's (:mod:`.fig1a`), "panel" with viser's plots.  The process's heap is set up for
    a long run first (:func:`.heap.fix_mmap_threshold`)."""
    fix_mmap_threshold()
    server = viser.ViserServer(host=host, port=port, label="dcmviz", verbose=False)
    try:
        dashboard = Dashboard(
            server, config, presets_dir=presets_dir, preset=preset, key=key,
            max_tabs=max_tabs, audience_push=audience_push, fig1a=fig1a,
            fig1a_port=next_free_port(host, server.get_port() + 1) if fig1a == "stream" else 0,
        )  # fmt: skip
    except BaseException:
        server.stop()
        raise
    return server, dashboard
