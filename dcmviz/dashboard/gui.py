"""Panel controls built from the preset schema (:func:`dcmviz.config.field_info`).

Every control is labelled ``symbol [unit]`` and takes its range from the schema's bounds, so a
control and the schema cannot disagree.  ``Controls`` only creates handles and writes values into
them; what a change means lives in :class:`~dcmviz.dashboard.editor.ConfigEditor`.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import viser

from dcmviz.config import Config, ControlSection, field_info
from dcmviz.robots import BUILTIN_ROBOTS, RobotSpec, load_robot


@dataclass(frozen=True)
class SliderSpec:
    section: str
    name: str
    step: float
    lo: float | None = None  # tighter than the schema, for usability (never looser)
    hi: float | None = None


FOOTSTEP_SLIDERS = (
    SliderSpec("gait", "n_steps", 1),
    SliderSpec("gait", "step_length", 0.01),
    SliderSpec("gait", "step_width", 0.01),
    SliderSpec("gait", "step_height", 0.01),
    SliderSpec("gait", "turn", 0.01),
    SliderSpec("gait", "t_ss", 0.05),
    SliderSpec("gait", "t_ds", 0.01),
    SliderSpec("gait", "t_start", 0.1),
    SliderSpec("gait", "t_stop", 0.1),
)
DCM_SLIDERS = (SliderSpec("dcm", "b", 0.001),)
CONTROL_SLIDERS = (
    SliderSpec("control", "k_xi", 0.1),
    SliderSpec("control", "max_step_adjustment", 0.01),
    SliderSpec("control", "k_f", 0.5),
)
# geometric fields: changing one regenerates the footsteps (drops dragged, explicit ones)
GEOMETRY_FIELDS = {"n_steps", "step_length", "step_width", "step_height", "turn", "first_swing"}


def label(section: str, name: str) -> str:
    """``symbol [unit]`` from the schema (the field name when it has no symbol)."""
    info = field_info(section, name)
    text = info["symbol"] or name
    return f"{text} [{info['unit']}]" if info["unit"] else text


# what the robot can do, for the sliders whose valid range depends on it (the preset validation
# refuses the rest: reach in dcmviz.robots.reach, CoM height in RobotSpec.height_problem)
ROBOT_BOUNDS: dict[tuple[str, str], Callable[[RobotSpec], tuple[float, float]]] = {
    ("gait", "step_length"): lambda r: (-r.max_step_length_m, r.max_step_length_m),
    ("gait", "step_width"): lambda r: (r.min_step_width_m, r.max_step_width_m),
    ("gait", "step_height"): lambda r: (-r.max_step_height_m, r.max_step_height_m),
    ("gait", "turn"): lambda r: (-r.max_turn_rad, r.max_turn_rad),
    ("dcm", "b"): lambda r: r.b_range_s,
}


def slider_range(spec: SliderSpec, robot: RobotSpec | None = None) -> tuple[float, float]:
    """(min, max) of a slider: the schema bounds (open bounds moved in by one step), within what
    ``robot`` can do, on the slider's grid (every position is a value validation accepts)."""
    info = field_info(spec.section, spec.name)
    lo = info.get("ge", info["gt"] + spec.step if "gt" in info else 0.0)
    hi = info.get("le", info["lt"] - spec.step if "lt" in info else lo + 100 * spec.step)
    if spec.lo is not None:
        lo = max(lo, spec.lo)
    if spec.hi is not None:
        hi = min(hi, spec.hi)
    bounds = ROBOT_BOUNDS.get((spec.section, spec.name))
    if robot is not None and bounds is not None:
        r_lo, r_hi = bounds(robot)
        lo, hi = max(lo, r_lo), min(hi, r_hi)
    lo = math.ceil(lo / spec.step - 1e-9) * spec.step  # inwards onto the grid
    hi = math.floor(hi / spec.step + 1e-9) * spec.step
    return round(lo, 6), round(hi, 6)


RECOVERY_STRATEGIES: tuple[str, ...] = ControlSection.model_fields["recovery"].annotation.__args__
ALL_SLIDERS = FOOTSTEP_SLIDERS + DCM_SLIDERS + CONTROL_SLIDERS


class Controls:
    """Handles for every config field, keyed by ``(section, name)``."""

    def __init__(self, gui: viser.GuiApi, config: Config) -> None:
        self.gui = gui
        self.handles: dict[tuple[str, str], viser.GuiInputHandle[Any]] = {}
        self._quiet = threading.local()
        self.extra: dict[str, Any] = {}
        self._callback: Callable[[str, str, Any, viser.ClientHandle | None], None] | None = None
        self.robot = load_robot(config.robot.model).spec

        with gui.add_folder("Footsteps"):
            for spec in FOOTSTEP_SLIDERS:
                self._slider(spec, config)
            self._dropdown("gait", "first_swing", ("left", "right"), config)
            self.extra["reset_footsteps"] = gui.add_button(
                "Regenerate footsteps", hint="Drop dragged footsteps, use the generated ones"
            )
            self.extra["gizmos"] = gui.add_checkbox(
                "Drag footsteps in 3D",
                initial_value=False,
                hint="A gizmo on each footstep; dragging one makes the footsteps explicit",
            )
        with gui.add_folder("DCM (Table I)"):
            self._dropdown("dcm", "order", ("0", "1", "3", "5"), config)
            for spec in DCM_SLIDERS:
                self._slider(spec, config)
            self.extra["dz_vrp"] = gui.add_markdown("")
        with gui.add_folder("Control (§III)"):
            self._slider(CONTROL_SLIDERS[0], config)
            self._checkbox("control", "step_adjustment", "Step adjustment (eqs. 27–35)", config)
            self._slider(CONTROL_SLIDERS[1], config)
            self._dropdown("control", "recovery", RECOVERY_STRATEGIES, config)  # issue 11
            self._checkbox("control", "observer", "Disturbance observer (eqs. 42–49)", config)
            self._slider(CONTROL_SLIDERS[2], config)

    # -- construction ---------------------------------------------------------------------------
    def _slider(self, spec: SliderSpec, config: Config) -> None:
        lo, hi = slider_range(spec, self.robot)
        value = getattr(getattr(config, spec.section), spec.name)
        info = field_info(spec.section, spec.name)
        handle = self.gui.add_slider(
            label(spec.section, spec.name),
            min=lo,
            max=hi,
            step=spec.step,
            initial_value=min(max(value, lo), hi),
            hint=info["description"],
        )
        self.handles[(spec.section, spec.name)] = handle

    def _dropdown(self, section: str, name: str, options: tuple[str, ...], config: Config) -> None:
        info = field_info(section, name)
        value = str(getattr(getattr(config, section), name))
        handle = self.gui.add_dropdown(
            label(section, name), options, initial_value=value, hint=info["description"] or None
        )
        self.handles[(section, name)] = handle

    def _checkbox(self, section: str, name: str, text: str, config: Config) -> None:
        info = field_info(section, name)
        handle = self.gui.add_checkbox(
            text, initial_value=bool(getattr(getattr(config, section), name)),
            hint=info["description"] or None,
        )  # fmt: skip
        self.handles[(section, name)] = handle

    def add_field_dropdown(
        self, section: str, name: str, text: str, options: tuple[str, ...], config: Config
    ) -> None:
        """A dropdown for a schema field outside the three tuning folders (mode, backend, robot)."""
        info = field_info(section, name)
        handle = self.gui.add_dropdown(
            text, options, initial_value=str(getattr(getattr(config, section), name)),
            hint=info["description"] or None,
        )  # fmt: skip
        self.handles[(section, name)] = handle
        if self._callback is not None:
            handle.on_update(self._forward(section, name, self._callback))

    # -- wiring -----------------------------------------------------------------------------------
    def on_change(
        self, callback: Callable[[str, str, Any, viser.ClientHandle | None], None]
    ) -> None:
        """Call ``callback(section, name, value, client)`` when a user changes a control."""
        self._callback = callback
        for (section, name), handle in self.handles.items():
            handle.on_update(self._forward(section, name, callback))

    def _forward(self, section: str, name: str, callback: Callable) -> Callable:
        def forward(event: viser.GuiEvent) -> None:
            if getattr(self._quiet, "on", False):
                return  # a value written by show(), not by a user
            callback(section, name, event.target.value, event.client)

        return forward

    def set_robot(self, robot: RobotSpec) -> None:
        """Slider ranges for ``robot`` (reach, CoM height): exactly what validation accepts."""
        self.robot = robot
        for spec in ALL_SLIDERS:
            handle = self.handles.get((spec.section, spec.name))
            if handle is None or (spec.section, spec.name) not in ROBOT_BOUNDS:
                continue
            lo, hi = slider_range(spec, robot)
            if (handle.min, handle.max) != (lo, hi):
                handle.min, handle.max = lo, hi

    def apply_ranges(self, ranges: dict[tuple[str, str], tuple[float, float]]) -> None:
        """Set slider ranges (from :func:`dcmviz.dashboard.ranges.valid_range`)."""
        for key, (lo, hi) in ranges.items():
            handle = self.handles.get(key)
            if handle is not None and (handle.min, handle.max) != (lo, hi):
                handle.min, handle.max = lo, hi

    def static_range(self, section: str, name: str) -> tuple[float, float, float]:
        """(min, max, step) of a slider for the robot alone (the schema within its reach)."""
        spec = next(s for s in ALL_SLIDERS if (s.section, s.name) == (section, name))
        lo, hi = slider_range(spec, self.robot)
        return lo, hi, spec.step

    def show(self, config: Config) -> None:
        """Write a config into the controls without triggering the change callbacks."""
        robot = load_robot(config.robot.model).spec
        if robot != self.robot:
            self.set_robot(robot)
        self._quiet.on = True
        try:
            dropdown = self.handles.get(("robot", "model"))
            if dropdown is not None and config.robot.model not in dropdown.options:
                # the built-in robots plus the loaded preset's robot file
                dropdown.options = (*BUILTIN_ROBOTS, config.robot.model)
            for (section, name), handle in self.handles.items():
                value = getattr(getattr(config, section), name)
                if isinstance(handle.value, str):
                    value = str(value)
                elif isinstance(handle.value, bool):
                    value = bool(value)
                handle.value = value
        finally:
            self._quiet.on = False


def parse_value(config: Config, section: str, name: str, value: Any) -> Any:
    """Control value → the schema's type (dropdown strings back to ints for the order)."""
    current = getattr(getattr(config, section), name)
    if isinstance(current, bool):
        return bool(value)
    if isinstance(current, int) and isinstance(value, str):
        try:
            return int(value)
        except ValueError:
            return value  # let the schema name the bad value
    if isinstance(current, int) and isinstance(value, float) and value.is_integer():
        return int(value)
    return value
