"""The dashboard: GUI handles + small callbacks that change one shared state, and draw_* readers.

One :class:`Dashboard` per server.  All GUI and scene nodes are server-level, so every browser tab
sees the same session; only notifications and downloads go to the client that asked.

State flows one way:  control → :meth:`Dashboard.apply_config` (validate, keep the last good
config) → preview worker (samples + draws the plan) and simulation loop (resets the session).
"""

from __future__ import annotations

import math
import shutil
import tempfile
import threading
import time
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np
import viser

from dcmviz import GRAVITY
from dcmviz.config import (
    MAX_PRESET_BYTES,
    Config,
    ConfigError,
    config_from_dict,
    dumps_preset,
    load_preset,
    loads_preset,
)
from dcmviz.dashboard import scene as draw
from dcmviz.dashboard.guard import install_guard
from dcmviz.dashboard.gui import GEOMETRY_FIELDS, Controls, parse_value
from dcmviz.dashboard.loop import SimLoop
from dcmviz.dashboard.plots import LivePlot, PreviewPlots
from dcmviz.dashboard.preview import PHASE_COLORS, PreviewData, preview_data
from dcmviz.dashboard.render import SimView
from dcmviz.gait import GaitPlan, plan_footsteps, plan_from_config
from dcmviz.record import Recorder
from dcmviz.robots import get_spec

CURRENT = "(current)"


def _session_factory(config: Config) -> Any:
    from dcmviz.session import Session

    return Session(config, backend=config.sim.backend)


class PreviewWorker:
    """Draws the latest submitted plan off the callers' threads (changes coalesce)."""

    def __init__(self, dashboard: Dashboard) -> None:
        self.dashboard = dashboard
        self._cond = threading.Condition()
        self._pending: tuple[int, GaitPlan, Config, float] | None = None
        self.drawn_version = -1
        self.draws = 0  # plans drawn (continuous mode redraws the receding horizon)
        self.latency_s: dict[int, float] = {}  # version → submit-to-drawn seconds
        self.cpu_s: dict[int, float] = {}  # version → CPU seconds of this thread to draw it
        self.data: PreviewData | None = None
        self._thread = threading.Thread(target=self._run, name="dcmviz-preview", daemon=True)
        self._stop = False
        self._thread.start()

    def submit(self, version: int, plan: GaitPlan, config: Config, t_submit: float) -> None:
        with self._cond:
            self._pending = (version, plan, config, t_submit)
            self._cond.notify()

    def wait(self, version: int, timeout: float = 5.0) -> bool:
        """Block until ``version`` (or a newer one) is drawn."""
        deadline = time.perf_counter() + timeout
        with self._cond:
            while self.drawn_version < version:
                left = deadline - time.perf_counter()
                if left <= 0:
                    return False
                self._cond.wait(left)
        return True

    def stop(self) -> None:
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        self._thread.join(timeout=5.0)

    def _run(self) -> None:
        while True:
            with self._cond:
                while self._pending is None and not self._stop:
                    self._cond.wait()
                if self._stop:
                    return
                version, plan, config, t_submit = self._pending
                self._pending = None
            cpu0 = time.thread_time()
            try:
                self.data = self.dashboard.draw_plan(plan, config)
            except Exception as err:  # noqa: BLE001 - a drawing bug must not stop the worker
                print(f"dcmviz: preview drawing failed: {err!r}")
            with self._cond:
                self.drawn_version = max(self.drawn_version, version)
                self.draws += 1
                self.latency_s[version] = time.perf_counter() - t_submit
                self.cpu_s[version] = time.thread_time() - cpu0
                self._cond.notify_all()


class Dashboard:
    """The dcmviz dashboard on one viser server."""

    def __init__(
        self,
        server: viser.ViserServer,
        config: Config,
        *,
        presets_dir: Path | str = "presets",
        start: bool = True,
        session_factory: Any = _session_factory,
        preset: str = CURRENT,
    ) -> None:
        self._initial_preset = preset  # shown in the preset dropdown (a stem of presets_dir)
        self.server = server
        install_guard(server, notify=self._notify_client)
        self.config = config  # the last good configuration
        self.version = 0
        self.presets_dir = Path(presets_dir)
        self._lock = threading.RLock()
        self._gizmos: list[viser.TransformControlsHandle] = []
        self._gizmo_quiet = threading.local()
        self.recorder: Recorder | None = None
        # (title, body) of the latest notifications sent (bounded: a hostile client cannot grow it)
        self.notifications: deque[tuple[str, str]] = deque(maxlen=200)
        self.loop = SimLoop(session_factory, config, on_event=self._on_sim_event)
        self._setup_scene()
        self._setup_gui()
        self.preview = PreviewWorker(self)
        self.view = SimView(self)
        self._submit_preview(time.perf_counter())
        if start:
            self.loop.start()
            self.view.start()

    # =============================================================================================
    # setup
    def _setup_scene(self) -> None:
        scene = self.server.scene
        scene.set_up_direction("+z")
        scene.add_grid(
            "/grid", width=12.0, height=12.0, cell_size=0.1, section_size=1.0,
            plane="xy", position=(0.0, 0.0, -0.001), cell_color=(220, 220, 220),
            section_color=(170, 170, 170), infinite_grid=True, fade_distance=30.0,
        )  # fmt: skip
        scene.add_light_hemisphere("/light/sky", intensity=0.8)
        scene.add_light_directional("/light/sun", intensity=1.5, position=(2.0, -3.0, 5.0))
        camera = self.server.initial_camera
        camera.position = (3.1, -2.4, 1.6)
        camera.look_at = (1.05, 0.3, 0.5)

    def _setup_gui(self) -> None:
        gui = self.server.gui
        gui.configure_theme(
            control_width="large", show_share_button=False, brand_color=(30, 60, 200)
        )
        self.gui_status = gui.add_markdown("**dcmviz** starting…")
        tabs = gui.add_tab_group()
        with tabs.add_tab("Plan", viser.Icon.SHOE):
            self.controls = Controls(gui, self.config)
            self.controls.on_change(self.on_field_change)
            self.controls.extra["reset_footsteps"].on_click(
                lambda event: self.on_regenerate_footsteps(event.client)
            )
            self.controls.extra["gizmos"].on_update(lambda _: self.draw_gizmos(self._plan))
        with tabs.add_tab("Simulate", viser.Icon.PLAYER_PLAY):
            self._setup_sim_gui(gui)
            self._setup_legend(gui)
            self._setup_push_gui(gui)
        with tabs.add_tab("Presets", viser.Icon.FILE_SETTINGS):
            self._setup_preset_gui(gui)
        self._setup_plot_panel(gui)
        self._plan = plan_from_config(self.config)
        self._show_config_extras(self.config)

    def _setup_plot_panel(self, gui: viser.GuiApi) -> None:
        """A second panel, docked left: the preview over time (Fig. 1a) and the live DCM."""
        self.plot_panel = gui.add_panel()
        with self.plot_panel.add_tab("Preview (Fig. 1a)", viser.Icon.CHART_LINE):
            gui.add_markdown(_phase_legend())
            self.preview_plots = PreviewPlots(gui)
        with self.plot_panel.add_tab("Live DCM", viser.Icon.ACTIVITY):
            self.gui_live_axis = gui.add_dropdown("axis", ("x", "y", "z"), initial_value="y")
            self.live_plot = LivePlot(gui, "y")
            self.gui_live_axis.on_update(lambda event: self.live_plot.set_axis(event.target.value))
        self.plot_panel.dock_left()
        self.plot_panel.set_width(400)

    def _setup_sim_gui(self, gui: viser.GuiApi) -> None:
        with gui.add_folder("Simulation"):
            self.gui_play = gui.add_button("Pause", icon=viser.Icon.PLAYER_PAUSE)
            self.gui_play.on_click(lambda event: self.on_play(not self.loop.playing))
            self.gui_reset = gui.add_button("Reset", icon=viser.Icon.REFRESH)
            self.gui_reset.on_click(lambda event: self.on_reset())
            self.gui_speed = gui.add_slider(
                "speed [×]", min=0.1, max=2.0, step=0.05, initial_value=1.0,
                hint="Simulated seconds per wall-clock second",
            )  # fmt: skip
            self.gui_speed.on_update(lambda event: self.on_speed(event.target.value))
            self.controls.add_field_dropdown(
                "gait", "mode", "mode", ("plan", "continuous"), self.config
            )
            self.controls.add_field_dropdown(
                "sim", "backend", "backend", ("mujoco", "lip"), self.config
            )
            self.controls.add_field_dropdown(
                "robot", "model", "robot", ("talos", "g1"), self.config
            )
            self.gui_loop = gui.add_checkbox(
                "Loop the plan", initial_value=True, hint="Restart when the plan has ended"
            )
            self.gui_loop.on_update(lambda event: self.loop.post("loop", event.target.value))
            self.gui_follow = gui.add_checkbox(
                "Camera follows the robot", initial_value=False,
                hint="Every open view keeps its angle and moves with the robot",
            )  # fmt: skip

    def _setup_legend(self, gui: viser.GuiApi) -> None:
        gui.add_markdown(
            "<small>On the floor (shifted down by Δz_vrp): "
            "<span style='color:#00aaff'>●</span> measured DCM ξ · "
            "<span style='color:#ff00c8'>●</span> adapted DCM ξ_adj · "
            "<span style='color:#ffc800'>●</span> commanded VRP. Footsteps: "
            "<span style='color:#ff00c8'>▭</span> adjusted (ghosts) · "
            "<span style='color:#3c3c3c'>▬</span> realised.</small>"
        )

    def _setup_push_gui(self, gui: viser.GuiApi) -> None:
        with gui.add_folder("Push"):
            self.gui_push_direction = gui.add_slider(
                "direction ψ_F [deg]", min=-180.0, max=180.0, step=5.0, initial_value=90.0,
                hint="0 = forward (+x), 90 = left (+y)",
            )  # fmt: skip
            self.gui_push_magnitude = gui.add_slider(
                "|F| [N]", min=0.0, max=1000.0, step=5.0, initial_value=150.0
            )
            self.gui_push_duration = gui.add_slider(
                "T_push [s]", min=0.05, max=10.0, step=0.05, initial_value=0.2
            )
            self.gui_push_ramp = gui.add_slider(
                "T_ramp [s]", min=0.0, max=10.0, step=0.05, initial_value=0.0
            )
            bodies = tuple(get_spec(self.config.robot.model).bodies)
            self.gui_push_body = gui.add_dropdown("body", bodies, initial_value=bodies[0])
            self.push_handles = {
                "direction": self.gui_push_direction,
                "magnitude": self.gui_push_magnitude,
                "duration": self.gui_push_duration,
                "ramp": self.gui_push_ramp,
            }
            self.gui_push = gui.add_button("Push", color="red", icon=viser.Icon.HAND_STOP)
            self.gui_push.on_click(lambda event: self.on_push(event.client))
            gui.add_markdown(
                "<small>Or click the robot: it is pushed at that body along the view "
                "direction. Arrows: <span style='color:#e61e1e'>applied force</span>, "
                "<span style='color:#1eaa3c'>observer estimate F̂</span> (above the head)."
                "</small>"
            )

    def _setup_preset_gui(self, gui: viser.GuiApi) -> None:
        with gui.add_folder("Presets"):
            names = (CURRENT, *self.preset_names())
            initial = self._initial_preset if self._initial_preset in names else CURRENT
            self.gui_preset = gui.add_dropdown("preset", names, initial_value=initial)
            self.gui_preset.on_update(
                lambda event: self.on_preset_selected(event.target.value, event.client)
            )
            self.gui_upload = gui.add_upload_button(
                "Upload preset (.toml)", icon=viser.Icon.UPLOAD, mime_type=".toml,text/plain"
            )
            self.gui_upload.on_upload(
                lambda event: self.on_upload(
                    event.target.value.name, event.target.value.content, event.client
                )
            )
            self.gui_export = gui.add_button("Export preset", icon=viser.Icon.DOWNLOAD)
            self.gui_export.on_click(lambda event: self.on_export(event.client))
            self.gui_description = gui.add_markdown("")
        with gui.add_folder("Recording"):
            self.gui_record = gui.add_checkbox(
                "Record (rerun)", initial_value=False,
                hint="Capture a rerun recording; unticking offers the .rrd for download",
            )  # fmt: skip
            self.gui_record.on_update(
                lambda event: self.on_record(event.target.value, event.client)
            )

    # =============================================================================================
    # callbacks → state (no math here: build a Config, hand it on)
    def on_field_change(
        self, section: str, name: str, value: Any, client: viser.ClientHandle | None = None
    ) -> bool:
        """A control changed: a new config with that field, or a notification and a revert."""
        with self._lock:
            data = self.config.to_dict()
            data.setdefault(section, {})[name] = parse_value(self.config, section, name, value)
            if name in GEOMETRY_FIELDS:
                data[section].pop("footsteps", None)
            return self.apply_dict(data, client)

    def on_footstep_moved(
        self, index: int, position: np.ndarray, client: viser.ClientHandle | None = None
    ) -> bool:
        """A footstep was dragged in 3D: the plan's footsteps become explicit, one of them moved."""
        with self._lock:
            _, steps = plan_footsteps(self.config.gait)
            footsteps = [
                {"side": s.side, "position": [float(c) for c in s.position], "yaw": float(s.yaw)}
                for s in steps
            ]
            if not 0 <= index < len(footsteps):
                return False
            z = footsteps[index]["position"][2]
            footsteps[index]["position"] = [float(position[0]), float(position[1]), z]
            data = self.config.to_dict()
            data["gait"]["footsteps"] = footsteps
            return self.apply_dict(data, client)

    def on_regenerate_footsteps(self, client: viser.ClientHandle | None = None) -> bool:
        with self._lock:
            data = self.config.to_dict()
            data["gait"].pop("footsteps", None)
            return self.apply_dict(data, client)

    def on_preset_selected(self, name: str, client: viser.ClientHandle | None = None) -> bool:
        if name == CURRENT:
            return False
        try:
            config = load_preset(self.presets_dir / f"{name}.toml")
        except ConfigError as err:
            self.notify(client, "Preset not loaded", str(err), error=True)
            self.gui_preset.value = CURRENT
            return False
        return self.apply_config(config, client, preset=name)

    def on_upload(self, filename: str, content: bytes, client: viser.ClientHandle | None) -> bool:
        """An uploaded TOML preset: size-limited, validated, adopted or refused with a reason."""
        if len(content) > MAX_PRESET_BYTES:
            self.notify(
                client, "Preset refused",
                f"{filename}: {len(content)} bytes; at most {MAX_PRESET_BYTES} allowed",
                error=True,
            )  # fmt: skip
            return False
        try:
            config = loads_preset(content.decode("utf-8"))
        except UnicodeDecodeError:
            self.notify(client, "Preset refused", f"{filename}: not UTF-8 text", error=True)
            return False
        except ConfigError as err:
            self.notify(client, "Preset refused", f"{filename}: {err}", error=True)
            return False
        ok = self.apply_config(config, client)
        if ok:
            self.notify(client, "Preset loaded", f"{filename}: {config.name}")
        return ok

    def on_export(self, client: viser.ClientHandle | None) -> bytes:
        """The current config as TOML, sent to the client as a download."""
        text = dumps_preset(self.config).encode("utf-8")
        if client is not None:
            client.send_file_download(
                _slug(self.config.name) + ".toml", text, save_immediately=True
            )
        return text

    def on_push(self, client: viser.ClientHandle | None = None) -> bool:
        """Push button: direction and magnitude from the panel."""
        angle = math.radians(self.gui_push_direction.value)
        magnitude = float(self.gui_push_magnitude.value)
        direction = (math.cos(angle), math.sin(angle), 0.0)
        return self.push(direction, magnitude, self.gui_push_body.value, client)

    def on_body_click(self, body: str, event: viser.SceneNodePointerEvent) -> bool:
        """The robot was clicked: push that body along the horizontal view direction."""
        return self.push(event.ray_direction, self.gui_push_magnitude.value, body, event.client)

    def push(
        self, direction: Any, magnitude: float, body: str, client: viser.ClientHandle | None
    ) -> bool:
        d = np.array(direction, dtype=float)
        d[2] = 0.0
        n = float(np.linalg.norm(d))
        d = d / n if n > 1e-9 else np.array([0.0, 1.0, 0.0])
        force = tuple(float(c) for c in magnitude * d)
        duration, ramp = float(self.gui_push_duration.value), float(self.gui_push_ramp.value)
        push = {"start": 0.0, "duration": duration, "force": force, "ramp": ramp, "body": body}
        data = self.config.to_dict()
        data["pushes"] = [*data.get("pushes", []), push]
        try:
            config_from_dict(data)  # the schema validates a push (and its body) like a preset's
        except ConfigError as err:
            self.notify(client, "Push refused", str(err), error=True)
            return False
        self.loop.post("push", {"force": force, "duration": duration, "ramp": ramp, "body": body})
        return True

    def on_play(self, playing: bool) -> None:
        self.loop.post("play", playing)
        self.loop.playing = playing  # the button label follows at once
        self.gui_play.label = "Pause" if playing else "Play"
        self.gui_play.icon = viser.Icon.PLAYER_PAUSE if playing else viser.Icon.PLAYER_PLAY

    def on_reset(self) -> None:
        self.loop.post("reset")

    def on_speed(self, speed: float) -> None:
        self.loop.post("speed", float(speed))

    def on_record(self, recording: bool, client: viser.ClientHandle | None) -> bytes | None:
        """Start a rerun recording of the session, or stop it and offer the .rrd for download."""
        if recording:
            if self.recorder is not None:
                return None
            recorder = Recorder()
            path = Path(tempfile.mkdtemp(prefix="dcmviz-")) / (_slug(self.config.name) + ".rrd")
            try:
                self.loop.call(lambda session: recorder.start(session, path))
            except Exception as err:  # noqa: BLE001 - tell the user, keep the session running
                self.notify(client, "Recording failed", str(err), error=True)
                self.gui_record.value = False
                return None
            self.recorder = recorder
            return None
        recorder, self.recorder = self.recorder, None
        if recorder is None:
            return None
        path = Path(self.loop.call(lambda session: recorder.stop()))
        data = path.read_bytes()
        shutil.rmtree(path.parent, ignore_errors=True)
        if client is not None:
            client.send_file_download(path.name, data, save_immediately=True)
        self.notify(client, "Recording ready", f"{path.name}: {recorder.samples} samples")
        return data

    # =============================================================================================
    # the one place the config changes
    def apply_dict(self, data: dict[str, Any], client: viser.ClientHandle | None) -> bool:
        try:
            config = config_from_dict(data)
        except ConfigError as err:
            self._reject(str(err), client)
            return False
        return self.apply_config(config, client)

    def apply_config(
        self, config: Config, client: viser.ClientHandle | None = None, *, preset: str = CURRENT
    ) -> bool:
        """Adopt a validated config: preview it, hand it to the simulation, show it in the panel.

        ``preset`` names the preset file it came from (the dropdown shows it until the next edit).
        """
        t_submit = time.perf_counter()
        with self._lock:
            try:
                plan = plan_from_config(config)
            except ValueError as err:
                self._reject(str(err), client)
                return False
            robot_changed = config.robot.model != self.config.robot.model
            self.config = config
            self._plan = plan
            self.version += 1
            version = self.version
            self.loop.post("config", (version, config))
            self.preview.submit(version, plan, config, t_submit)
            self.controls.show(config)
            self._show_config_extras(config)
            self.gui_preset.value = preset  # its callback ignores CURRENT
            if robot_changed:
                bodies = tuple(get_spec(config.robot.model).bodies)
                self.gui_push_body.options = bodies
        return True

    def _reject(self, message: str, client: viser.ClientHandle | None) -> None:
        """Tell the user what is wrong and put the controls back to the last good config."""
        self.notify(client, "Invalid value", message, error=True)
        self.controls.show(self.config)
        self.draw_gizmos(self._plan)

    def _submit_preview(self, t_submit: float) -> None:
        self.preview.submit(self.version, self._plan, self.config, t_submit)

    def _show_config_extras(self, config: Config) -> None:
        b = config.dcm.b
        self.controls.extra[
            "dz_vrp"
        ].content = f"Δz_vrp = g b² = {GRAVITY:.2f} · {b:.3f}² = **{GRAVITY * b * b:.3f} m**"
        if hasattr(self, "gui_description"):
            self.gui_description.content = (
                f"**{config.name}**  \n{config.description}" if config.description else
                f"**{config.name}**"
            )  # fmt: skip

    def preset_names(self) -> list[str]:
        return sorted(p.stem for p in self.presets_dir.glob("*.toml"))

    def notify(
        self, client: viser.ClientHandle | None, title: str, body: str, *, error: bool = False
    ) -> None:
        """A notification to one client (or all clients when the event has none)."""
        self.notifications.append((title, body))
        clients = [client] if client is not None else list(self.server.get_clients().values())
        for c in clients:
            try:
                c.add_notification(
                    title, body, auto_close_seconds=8.0 if error else 4.0,
                    color="red" if error else "blue",
                )  # fmt: skip
            except Exception:  # noqa: BLE001 - a client that just closed
                pass

    def _notify_client(self, client_id: int, title: str, body: str) -> None:
        """A notification to the client with this id (the guard's refusals)."""
        client = self.server.get_clients().get(client_id)
        if client is not None:
            self.notify(client, title, body, error=True)

    def _on_sim_event(self, kind: str, message: str) -> None:
        self.notify(None, "Fall" if kind == "fell" else "Simulation", message, error=True)

    # =============================================================================================
    # drawing (preview worker thread)
    def draw_plan(self, plan: GaitPlan, config: Config) -> PreviewData:
        """Sample the plan and redraw the 3D preview, the gizmos and the Fig. 1a plots."""
        data = preview_data(plan, get_spec(config.robot.model))
        scene = self.server.scene
        with self.server.atomic():
            draw.draw_footsteps(scene, data)
            draw.draw_preview(scene, data)
        self.draw_gizmos(plan)
        self.preview_plots.draw(data)
        return data

    def draw_gizmos(self, plan: GaitPlan) -> None:
        """One translation gizmo per footstep (xy plane) when dragging is enabled."""
        enabled = self.controls.extra["gizmos"].value
        steps = plan.steps if enabled else ()
        with self._lock:
            while len(self._gizmos) > len(steps):
                self._gizmos.pop().remove()
            for i, step in enumerate(steps):
                pos = np.asarray(step.position, float) + [0.0, 0.0, 0.01]
                if i < len(self._gizmos):
                    g = self._gizmos[i]
                    if np.linalg.norm(np.asarray(g.position) - pos) > 1e-6:
                        self._gizmo_quiet.on = True
                        try:
                            g.position = pos
                        finally:
                            self._gizmo_quiet.on = False
                    continue
                g = self.server.scene.add_transform_controls(
                    f"/gizmos/step_{i}", scale=0.18, line_width=2.0,
                    active_axes=(True, True, False), disable_rotations=True,
                    disable_sliders=False, depth_test=False, position=pos,
                )  # fmt: skip
                g.on_update(self._gizmo_callback(i))
                self._gizmos.append(g)

    def _gizmo_callback(self, index: int) -> Any:
        def moved(event: viser.TransformControlsEvent) -> None:
            if getattr(self._gizmo_quiet, "on", False):
                return
            self.on_footstep_moved(index, np.asarray(event.target.position), event.client)

        return moved

    # =============================================================================================
    def stop(self) -> None:
        self.view.stop()
        self.loop.stop()
        self.preview.stop()


def _slug(name: str) -> str:
    slug = "".join(c.lower() if c.isalnum() else "_" for c in name).strip("_")
    return slug or "dcmviz_preset"


def _phase_legend() -> str:
    items = []
    for kind, (r, g, b) in PHASE_COLORS.items():
        items.append(f"<span style='color:rgb({r},{g},{b})'>■</span> {kind}")
    return (
        "<small>VRP by phase: " + " ".join(items) + " · <span style='color:#1e3cc8'>━</span> DCM"
        "</small>"
    )


def serve(
    config: Config,
    *,
    host: str = "127.0.0.1",
    port: int = 8080,
    presets_dir: Path | str = "presets",
    preset: str = CURRENT,
) -> tuple[viser.ViserServer, Dashboard]:
    """A viser server on ``host:port`` with the dashboard running ``config`` (from ``preset``)."""
    server = viser.ViserServer(host=host, port=port, label="dcmviz", verbose=False)
    return server, Dashboard(server, config, presets_dir=presets_dir, preset=preset)
