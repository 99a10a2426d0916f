"""Planning facts about a robot: size, reach, feet, bodies (no MuJoCo).

A :class:`RobotSpec` comes from a robot file (``dcmviz/robots/data/*.toml`` for the built-ins,
any path for the user's): the numbers the file pins, the rest derived from its model with
Pinocchio (:mod:`dcmviz.robots.model`).  Importing this module is cheap; the first
:func:`get_spec` of a robot builds its Pinocchio model (≈ 0.1 s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from dcmviz import GRAVITY
from dcmviz.dcm.control import vrp_height


@dataclass(frozen=True)
class RobotSpec:
    name: str
    mass_kg: float  # total mass of the simulated model
    com_height_m: float  # CoM above the soles in the nominal standing posture
    foot_length_m: float  # sole support rectangle, x extent
    foot_width_m: float  # sole support rectangle, y extent
    foot_spacing_m: float  # nominal lateral distance between the sole centres
    max_step_length_m: float  # reach: |Δx| of one step relative to the stance foot
    max_step_width_m: float  # reach: largest lateral distance between the feet
    min_step_width_m: float  # feet closer than this collide
    max_step_height_m: float  # |Δz| of one step
    # mean horizontal sole speed over single support (lift-off → touchdown distance / T_ss)
    max_swing_speed_m_s: float
    min_com_height_m: float  # lowest CoM height above the soles the robot walks at
    max_com_height_m: float  # highest (knees still bent enough to walk)
    bodies: dict[str, str]  # push target name -> link name in the URDF
    max_turn_rad: float = 0.5  # |yaw| per generated step (gait.turn); 0.5: the schema's bound
    # hip–ankle distance (m) when standing at max_com_height_m: the legs stretch no further while
    # walking, so feet far apart lower the CoM (dcmviz.gait.height); None: no such limit
    leg_length_m: float | None = None

    @property
    def b_nominal_s(self) -> float:
        """b = sqrt(Δz_vrp / g) with Δz_vrp the nominal CoM height (eq. 1)."""
        return (self.com_height_m / GRAVITY) ** 0.5

    @property
    def com_height_range_m(self) -> tuple[float, float]:
        """CoM heights above the soles (m) the robot walks at."""
        return (self.min_com_height_m, self.max_com_height_m)

    @property
    def b_range_s(self) -> tuple[float, float]:
        """(b_min, b_max) in s: b = sqrt(Δz_vrp / g) with Δz_vrp = the CoM height (eq. 1).

        The range a b control offers for this robot.
        """
        return (
            (self.min_com_height_m / GRAVITY) ** 0.5,
            (self.max_com_height_m / GRAVITY) ** 0.5,
        )

    def height_problem(self, b: float) -> str:
        """'' if Δz_vrp = g b² is a CoM height the robot walks at, else why not."""
        height = vrp_height(b)
        lo, hi = self.com_height_range_m
        if lo - 1e-9 <= height <= hi + 1e-9:
            return ""
        b_lo, b_hi = self.b_range_text()
        return (
            f"asks for a CoM height of {height:.3f} m; {self.name} walks at "
            f"{lo:.3f}–{hi:.3f} m, i.e. b from {b_lo} to {b_hi} s"
        )

    def b_range_text(self, decimals: int = 3) -> tuple[str, str]:
        """b's range rounded inwards to ``decimals``: every b written with that many decimals
        between the two is one the robot walks at (0.2714–0.3027 s reads 0.272–0.302, not
        0.271–0.303, both of which are refused)."""
        lo, hi = self.b_range_s
        q = 10**decimals
        return (
            f"{math.ceil(lo * q - 1e-9) / q:.{decimals}f}",
            f"{math.floor(hi * q + 1e-9) / q:.{decimals}f}",
        )
