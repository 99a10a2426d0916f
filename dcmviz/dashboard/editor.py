"""The one place the dashboard's configuration changes.

A control, a dragged footstep, a preset or an upload becomes a candidate :class:`Config`; it is
validated (the schema, then the plan), adopted (``config`` and ``version`` move on), posted to the
simulation loop, and announced to whoever listens (panels show it; the plan view waits for the
walk to pick it up).  A refused candidate is told to the user and the controls go back.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from typing import Any

import numpy as np
import viser

from dcmviz.config import PRESETS_DOC, Config, ConfigError, config_from_dict
from dcmviz.dashboard.feasibility import plan_warnings
from dcmviz.dashboard.gui import DCM_SLIDERS, GEOMETRY_FIELDS, parse_value
from dcmviz.dashboard.loop import SimLoop
from dcmviz.dashboard.notify import Notifier
from dcmviz.gait import PlanWarning, plan_footsteps, plan_from_config
from dcmviz.robots import load_robot

CURRENT = "(current)"  # the preset dropdown's entry for a configuration edited in the panel

B_STEP = DCM_SLIDERS[0].step  # s, the b slider's step

Applied = Callable[[Config, str], None]  # (config, preset name or CURRENT)
Rejected = Callable[[Config], None]  # (the config kept)


def fit_b_to_robot(data: dict[str, Any], step: float = B_STEP) -> None:
    """A b the newly chosen robot cannot walk at becomes its nominal b (CoM at standing height)
    on the b slider's grid, so picking another robot is never refused for the previous one's b."""
    try:
        spec = load_robot(data["robot"]["model"]).spec
    except (KeyError, ValueError):
        return  # the schema names the bad robot
    lo, hi = spec.b_range_s
    b = data.setdefault("dcm", {}).get("b")
    if not isinstance(b, float | int) or not lo <= b <= hi:
        n_lo, n_hi = math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9)  # grid inside
        n = min(max(round(spec.b_nominal_s / step), n_lo), n_hi)
        data["dcm"]["b"] = round(n * step, 6)


class ConfigEditor:
    """Holds the last good config and its version; every change goes through :meth:`apply_config`."""

    def __init__(self, config: Config, loop: SimLoop, notifier: Notifier) -> None:
        self.config = config
        self.version = 0
        self.warnings: tuple[PlanWarning, ...] = ()  # feasibility of the last adopted edit's plan
        self.loop = loop
        self.notifier = notifier
        self._lock = threading.RLock()
        self._applied: list[Applied] = []
        self._rejected: list[Rejected] = []

    def on_applied(self, listener: Applied) -> None:
        """Call ``listener(config, preset)`` after a config was adopted."""
        self._applied.append(listener)

    def on_rejected(self, listener: Rejected) -> None:
        """Call ``listener(config)`` with the kept config after a candidate was refused."""
        self._rejected.append(listener)

    # -- edits ----------------------------------------------------------------------------------
    def on_field_change(
        self, section: str, name: str, value: Any, client: viser.ClientHandle | None = None
    ) -> bool:
        """A control changed: a new config with that field, or a notification and a revert."""
        with self._lock:
            data = self.config.to_dict()
            data.setdefault(section, {})[name] = parse_value(self.config, section, name, value)
            if name in GEOMETRY_FIELDS:
                data[section].pop("footsteps", None)
            if (section, name) == ("robot", "model"):
                fit_b_to_robot(data)
            return self.apply_dict(data, client)

    def on_footstep_moved(
        self, index: int, position: np.ndarray, client: viser.ClientHandle | None = None
    ) -> bool:
        """A footstep was dragged in 3D: the plan's footsteps become explicit, one of them moved."""
        with self._lock:
            _, steps = plan_footsteps(self.config.gait)
            if not 0 <= index < len(steps):
                return False
            footsteps = [
                {"side": s.side, "position": [float(c) for c in s.position], "yaw": float(s.yaw)}
                for s in steps
            ]
            z = footsteps[index]["position"][2]
            footsteps[index]["position"] = [float(position[0]), float(position[1]), z]
            data = self.config.to_dict()
            data["gait"]["footsteps"] = footsteps
            return self.apply_dict(data, client)

    def on_regenerate_footsteps(self, client: viser.ClientHandle | None = None) -> bool:
        """Drop explicit (dragged) footsteps: the generated ones again."""
        with self._lock:
            data = self.config.to_dict()
            data["gait"].pop("footsteps", None)
            return self.apply_dict(data, client)

    # -- adoption -------------------------------------------------------------------------------
    def apply_dict(self, data: dict[str, Any], client: viser.ClientHandle | None) -> bool:
        try:
            config = config_from_dict(data)
        except ConfigError as err:
            self.reject(str(err), client)
            return False
        return self.apply_config(config, client)

    def apply_config(
        self, config: Config, client: viser.ClientHandle | None = None, *, preset: str = CURRENT
    ) -> bool:
        """Adopt a validated config and hand it to the simulation (which says what it did).

        ``preset`` names the preset file it came from (the dropdown shows it until the next edit).
        """
        with self._lock:
            try:
                plan = plan_from_config(config)  # a plan can be built (footsteps within reach, …)
            except ValueError as err:
                self.reject(str(err), client)
                return False
            self.warnings = plan_warnings(plan, config)  # shown before the walk takes it
            self.config = config
            self.version += 1
            self.loop.post("config", (self.version, config))
            for listener in list(self._applied):
                listener(config, preset)
        return True

    def reject(self, message: str, client: viser.ClientHandle | None) -> None:
        """Tell the user what is wrong and put the controls back to the last good config."""
        self.notifier.notify(
            client, "Invalid value", f"{message} (limits: {PRESETS_DOC})", error=True
        )
        for listener in list(self._rejected):
            listener(self.config)
