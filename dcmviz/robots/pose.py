"""Where a humanoid's links are: the pose a backend reports and the visual model draws."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RobotPose:
    """Where a humanoid's links are: floating base and joint angles (for drawing and recording)."""

    base_position: np.ndarray  # (3,) m, world
    base_wxyz: np.ndarray  # (4,) unit quaternion (w, x, y, z)
    joints: dict[str, float]  # URDF joint name → angle (rad), locked joints included
