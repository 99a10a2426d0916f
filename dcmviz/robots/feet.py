"""The feet: their sides and a sole placement (a footstep).

World frame, z up, x forward; positions in m, yaw in rad about z.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SIDES = ("left", "right")
OTHER = {"left": "right", "right": "left"}
SIDE_SIGN = {"left": 1.0, "right": -1.0}


@dataclass(frozen=True)
class Footstep:
    """A sole placement: position of the sole frame origin (m, world) and yaw (rad)."""

    side: str
    position: np.ndarray
    yaw: float = 0.0

    def moved(self, position: np.ndarray) -> Footstep:
        return Footstep(self.side, np.asarray(position, dtype=float), self.yaw)
