"""The Simulation folder: reset, speed, walk mode, backend, robot, looping."""

from __future__ import annotations

import viser

from dcmviz.config import Config
from dcmviz.dashboard.gui import Controls
from dcmviz.dashboard.loop import SimLoop
from dcmviz.dashboard.time_panel import TimePanel
from dcmviz.robots import BUILTIN_ROBOTS


def robot_options(config: Config) -> tuple[str, ...]:
    """The robot dropdown: the built-in robots, then the loaded preset's robot file if any."""
    model = config.robot.model
    return BUILTIN_ROBOTS if model in BUILTIN_ROBOTS else (*BUILTIN_ROBOTS, model)


class SimPanel:
    """Handles ``gui_reset``, ``gui_speed``, ``gui_loop``; the mode, backend and robot dropdowns
    are config fields (they go through :class:`Controls`); play/pause is the Time folder's."""

    def __init__(
        self,
        gui: viser.GuiApi,
        loop: SimLoop,
        controls: Controls,
        config: Config,
        time_panel: TimePanel,
    ) -> None:
        self.loop = loop
        self.time_panel = time_panel
        with gui.add_folder("Simulation"):
            self.gui_reset = gui.add_button("Reset", icon=viser.Icon.REFRESH)
            self.gui_reset.on_click(lambda event: self.on_reset())
            self.gui_speed = gui.add_slider(
                "speed [×]", min=0.1, max=2.0, step=0.05, initial_value=1.0,
                hint="Simulated seconds per wall-clock second",
            )  # fmt: skip
            self.gui_speed.on_update(lambda event: self.on_speed(event.target.value))
            controls.add_field_dropdown("gait", "mode", "mode", ("plan", "continuous"), config)
            controls.add_field_dropdown("sim", "backend", "backend", ("mujoco", "lip"), config)
            controls.add_field_dropdown("robot", "model", "robot", robot_options(config), config)
            self.gui_loop = gui.add_checkbox(
                "Loop the plan", initial_value=True, hint="Restart when the plan has ended"
            )
            self.gui_loop.on_update(lambda event: self.loop.post("loop", event.target.value))

    def on_play(self, playing: bool) -> None:
        self.time_panel.on_play(playing)

    def on_reset(self) -> None:
        self.loop.post("reset")

    def on_speed(self, speed: float) -> None:
        self.loop.post("speed", float(speed))
