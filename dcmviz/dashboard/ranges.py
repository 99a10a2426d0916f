"""Slider ranges that are exactly what validation accepts for the robot and the other settings.

A slider's static range (:func:`~dcmviz.dashboard.gui.slider_range`: the schema within what the
robot can do) is not enough where the limit depends on other settings: how long a step may be
depends on the turn and the width (turning about the inner foot reaches further), how far a
step may turn depends on its length, and on a terrain a step may not change height at all.  For
those sliders :func:`valid_range` asks the preset validation itself (:func:`config_from_dict`,
about 0.4 ms a call) for the extreme values on the slider's grid, by bisection from the current
value (the valid values of each of these fields form one interval).
"""

from __future__ import annotations

import math
from typing import Any

from dcmviz.config import Config, ConfigError, config_from_dict

# the fields whose valid range depends on other settings (their sliders follow every edit)
DEPENDENT = (
    ("gait", "step_length"),
    ("gait", "step_width"),
    ("gait", "step_height"),
    ("gait", "turn"),
    ("dcm", "b"),
)
GEOMETRY = {"n_steps", "step_length", "step_width", "step_height", "turn", "first_swing"}


def accepts(data: dict[str, Any], section: str, name: str, value: float) -> bool:
    """Whether the preset ``data`` with ``section.name = value`` validates."""
    candidate = {**data, section: {**data.get(section, {}), name: value}}
    if name in GEOMETRY:
        candidate[section].pop("footsteps", None)  # as the editor does for a geometry edit
    try:
        config_from_dict(candidate)
    except (ConfigError, ValueError):
        return False
    return True


def valid_range(
    config: Config, section: str, name: str, lo: float, hi: float, step: float
) -> tuple[float, float]:
    """(min, max) on the grid of ``step`` within [lo, hi] that validation accepts for
    ``section.name`` with every other setting of ``config`` kept (the static range if the
    current value itself is not on it)."""
    data = config.to_dict()
    n_lo, n_hi = math.ceil(lo / step - 1e-9), math.floor(hi / step + 1e-9)
    current = getattr(getattr(config, section), name)
    k = min(max(round(current / step), n_lo), n_hi)
    if not accepts(data, section, name, round(k * step, 9)):
        return lo, hi

    def edge(good: int, bad_end: int) -> int:
        if accepts(data, section, name, round(bad_end * step, 9)):
            return bad_end
        bad = bad_end
        while abs(bad - good) > 1:
            mid = (good + bad) // 2
            if accepts(data, section, name, round(mid * step, 9)):
                good = mid
            else:
                bad = mid
        return good

    return round(edge(k, n_lo) * step, 6), round(edge(k, n_hi) * step, 6)
