"""The Push folder and click-to-push: a force on a body of the simulated robot, posted to the loop."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence

import numpy as np
import viser

from dcmviz.config import Config, ConfigError, config_from_dict
from dcmviz.dashboard.aim import PushAim, describe
from dcmviz.dashboard.editor import ConfigEditor
from dcmviz.dashboard.loop import SimLoop
from dcmviz.dashboard.notify import Notifier
from dcmviz.robots import load_robot

LAST_PUSH_SHOW_S = 4.0  # the status line names a click's push this long once it shows it
PUSH_N_PER_KG = 150.0 / 90.27  # a click's default |F|: 150 N on the 90 kg Talos, by mass
# a drag's spring: k = 5 N/m per kg (450 N/m on Talos: a 0.3 m pull is 135 N)
PULL_STIFFNESS_N_PER_M_KG = 5.0
PULL_DAMPING_RATIO = 0.3  # c = 2 ζ √(k m)
MAX_FORCE_N = 5000.0  # a push's |F| at most (the preset schema's bound)
MAX_DURATION_S = 600.0  # a push's T_push at most (the preset schema's bound)


def default_magnitude(mass_kg: float) -> float:
    """A click's default |F| for a robot of ``mass_kg``: PUSH_N_PER_KG × m on the 5 N grid."""
    return float(max(5.0, 5.0 * round(PUSH_N_PER_KG * mass_kg / 5.0)))


def spring(mass_kg: float) -> tuple[float, float]:
    """(stiffness N/m, damping N·s/m) of the drag's spring for a robot of ``mass_kg``."""
    k = PULL_STIFFNESS_N_PER_M_KG * mass_kg
    return k, 2.0 * PULL_DAMPING_RATIO * math.sqrt(k * mass_kg)


def horizontal_force(direction: Sequence[float], magnitude: float) -> tuple[float, float, float]:
    """``magnitude`` N along the horizontal part of ``direction`` (+y if it has none)."""
    d = np.array(direction, dtype=float)
    d[2] = 0.0
    n = float(np.linalg.norm(d))
    d = d / n if n > 1e-9 else np.array([0.0, 1.0, 0.0])
    return tuple(float(c) for c in magnitude * d)


def heading(direction_deg: float) -> tuple[float, float, float]:
    """Unit vector of a push direction ψ_F in the horizontal plane (0 = +x, 90 = +y)."""
    angle = math.radians(direction_deg)
    return (math.cos(angle), math.sin(angle), 0.0)


class PushPanel:
    """Handles ``gui_push_*``; :meth:`on_body_click` is what the robot's meshes call."""

    def __init__(
        self, gui: viser.GuiApi, loop: SimLoop, editor: ConfigEditor, notifier: Notifier
    ) -> None:
        self.loop = loop
        self.editor = editor
        self.notifier = notifier
        self.clicks = 0  # clicks on the robot that reached the server
        self.drags = 0  # drags of the robot that reached the server
        self.last_push = (-math.inf, "")  # (monotonic time, what the last click pushed)
        self._shown: tuple[float, float] | None = None  # (that time, when the status first read it)
        self.pulls: list[str] = []  # what each finished drag did (the log; the latest 50)
        self._drag: dict | None = None  # the drag in progress: body, start, peak force
        robot = load_robot(editor.config.robot.model)
        self.mass = robot.spec.mass_kg
        self.robot_name = robot.spec.name
        self._hint_listeners: list[Callable[[str], None]] = []
        self.aim: PushAim | None = None  # each tab's arrow (the dashboard sets it)
        # who pushed, for the status line ('' for the presenter; the dashboard's audience)
        self.who: Callable[[viser.ClientHandle | None], str] = lambda client: ""
        with gui.add_folder("Push"):
            self.gui_push_direction = gui.add_slider(
                "direction ψ_F [deg]", min=-180.0, max=180.0, step=5.0, initial_value=90.0,
                hint="0 = forward (+x), 90 = left (+y)",
            )  # fmt: skip
            self.gui_push_magnitude = gui.add_slider(
                "|F| [N]", min=0.0, max=MAX_FORCE_N, step=5.0,
                initial_value=default_magnitude(self.mass),
                hint="A push's force (the default scales with the robot's mass: "
                f"{PUSH_N_PER_KG:.2f} N per kg); a preset allows up to {MAX_FORCE_N:.0f} N",
            )  # fmt: skip
            self.gui_push_duration = gui.add_slider(
                "T_push [s]", min=0.05, max=MAX_DURATION_S, step=0.05, initial_value=0.2,
                hint="How long the force acts",
            )  # fmt: skip
            self.gui_push_ramp = gui.add_slider(
                "T_ramp [s]", min=0.0, max=0.2, step=0.05, initial_value=0.0,
                hint="Linear ramp-up at the start of the push (at most T_push)",
            )  # fmt: skip
            bodies = tuple(load_robot(editor.config.robot.model).spec.bodies)
            self.gui_push_body = gui.add_dropdown("body", bodies, initial_value=bodies[0])
            self.handles = {
                "direction": self.gui_push_direction,
                "magnitude": self.gui_push_magnitude,
                "duration": self.gui_push_duration,
                "ramp": self.gui_push_ramp,
            }
            self.gui_push = gui.add_button("Push", color="red", icon=viser.Icon.HAND_STOP)
            self.gui_push.on_click(
                notifier.guarded("Push", lambda event: self.on_push(event.client))
            )
            gui.add_markdown(
                "<small>Or click the robot: it is pushed at that body along your view, as "
                "the <span style='color:#ff8c00'>orange arrow</span> beside it shows. Or drag "
                "a body: a spring pulls it towards the pointer (its force drawn red, the "
                "spring as a line) until you let go. Arrows: "
                "<span style='color:#e61e1e'>applied force</span>, "
                "<span style='color:#1eaa3c'>observer estimate F̂</span> (above the head)."
                "</small>"
            )
        editor.on_applied(self.show)
        for handle in (self.gui_push_magnitude, self.gui_push_duration):
            handle.on_update(lambda _: self._hint_changed())
        # T_ramp's range is what a push accepts: at most T_push
        self.gui_push_duration.on_update(lambda _: self._fit_ramp())

    def hint(self) -> str:
        """What a click on the robot does, with the force it will apply."""
        return (
            f"Click the robot to push it: {self.gui_push_magnitude.value:.0f} N for "
            f"{self.gui_push_duration.value:.2f} s along your view, as the orange arrow shows "
            "(Simulate tab → Push)"
        )

    def click_force(self) -> tuple[float, float]:
        """What a click applies: (magnitude N, duration s)."""
        return float(self.gui_push_magnitude.value), float(self.gui_push_duration.value)

    def on_hint(self, listener: Callable[[str], None]) -> None:
        """Call ``listener(hint)`` when the force a click applies changes."""
        self._hint_listeners.append(listener)

    def _hint_changed(self) -> None:
        for listener in list(self._hint_listeners):
            listener(self.hint())

    def _fit_ramp(self) -> None:
        duration = float(self.gui_push_duration.value)
        if self.gui_push_ramp.max != duration:
            if self.gui_push_ramp.value > duration:
                self.gui_push_ramp.value = duration
            self.gui_push_ramp.max = duration

    def show(self, config: Config, preset: str) -> None:
        """The push bodies of the configured robot; another robot gets its own default |F|
        (by its mass: 500 N set for Talos would throw the 33 kg G1 across the room)."""
        robot = load_robot(config.robot.model)
        bodies = tuple(robot.spec.bodies)
        if tuple(self.gui_push_body.options) != bodies:
            self.gui_push_body.options = bodies
        if robot.spec.name != self.robot_name:
            self.robot_name = robot.spec.name
            self.mass = robot.spec.mass_kg
            magnitude = default_magnitude(self.mass)
            if self.gui_push_magnitude.value != magnitude:
                self.gui_push_magnitude.value = magnitude
                self.notifier.notify(
                    None, "Push reset",
                    f"|F| = {magnitude:.0f} N for the {self.mass:.0f} kg {robot.spec.name} "
                    f"({PUSH_N_PER_KG:.2f} N per kg)",
                )  # fmt: skip

    # -- callbacks ------------------------------------------------------------------------------
    def on_push(self, client: viser.ClientHandle | None = None) -> bool:
        """Push button: direction and magnitude from the panel."""
        force = horizontal_force(
            heading(self.gui_push_direction.value), self.gui_push_magnitude.value
        )
        return self.push(force, self.gui_push_body.value, client)

    def on_body_click(self, body: str, event: viser.SceneNodePointerEvent) -> bool:
        """The robot was clicked: push that body along the tab's horizontal view direction (what
        its aim arrow shows; the click ray's where the view is vertical or there is no aim)."""
        self.clicks += 1
        direction = event.ray_direction
        if self.aim is not None:
            direction = self.aim.direction(event.client, event.ray_direction)
        force = horizontal_force(direction, self.gui_push_magnitude.value)
        ok = self.push(force, body, event.client)
        if ok:  # the status line says it (a pop-up per click would cover the robot)
            who = self.who(event.client)
            self.last_push = (
                time.monotonic(),
                f"{who + ' ' if who else ''}pushed {body}: {describe(force)} "
                f"for {self.gui_push_duration.value:.2f} s",
            )
        return ok

    def on_body_drag(self, body: str, event: viser.SceneNodeDragEvent) -> None:
        """A body of the robot is dragged: a spring pulls it towards the pointer (MuJoCo's
        viewer's perturbation), stiffness by the robot's mass; released at the drag's end."""
        if event.phase == "start":
            self.drags += 1
            k, c = spring(self.mass)
            self._drag = {"body": body, "t": time.monotonic(), "stiffness": k}
            self.loop.post("pull", {
                "body": body, "target": tuple(event.end_position), "stiffness": k,
                "damping": c, "grab": tuple(event.start_position),
            })  # fmt: skip
        elif event.phase == "update" and self._drag is not None:
            k, c = spring(self.mass)
            self.loop.post("pull", {"body": self._drag["body"], "target":
                                    tuple(event.end_position), "stiffness": k, "damping": c})  # fmt: skip
        elif event.phase == "end" and self._drag is not None:
            self.loop.post("release")
            drag, self._drag = self._drag, None
            text = (f"pulled {drag['body']} for {time.monotonic() - drag['t']:.1f} s with a "
                    f"{drag['stiffness']:.0f} N/m spring")  # fmt: skip
            self.pulls = [*self.pulls[-49:], text]
            self.last_push = (time.monotonic(), text)

    def status(self, pulling: str = "") -> str:
        """The last click's push or drag for LAST_PUSH_SHOW_S from the first time the status
        line reads it (as the status line's notes: a page or a render thread slowed by a loaded
        machine still shows it that long), or the pull going on ('' otherwise: the Plan tab says
        what a click will do)."""
        if pulling:
            return pulling
        t, text = self.last_push
        if not text:
            return ""
        now = time.monotonic()
        if self._shown is None or self._shown[0] != t:
            self._shown = (t, now)
        return text if now - self._shown[1] < LAST_PUSH_SHOW_S else ""

    def push(
        self, force: tuple[float, float, float], body: str, client: viser.ClientHandle | None
    ) -> bool:
        """Validate a push of ``force`` N on ``body`` like a preset's, then post it."""
        duration, ramp = float(self.gui_push_duration.value), float(self.gui_push_ramp.value)
        push = {"start": 0.0, "duration": duration, "force": force, "ramp": ramp, "body": body}
        data = self.editor.config.to_dict()
        data["pushes"] = [*data.get("pushes", []), push]
        try:
            config_from_dict(data)  # the schema validates a push (and its body) like a preset's
        except ConfigError as err:
            self.notifier.notify(client, "Push refused", str(err), error=True)
            return False
        self.loop.post("push", {"force": force, "duration": duration, "ramp": ramp, "body": body})
        return True
