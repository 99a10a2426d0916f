"""Planning facts about each robot, cheap to import (no MuJoCo, no Pinocchio).

The numbers are checked against the loaded models in ``tests/test_robots.py``; the models
themselves are built in :mod:`dcmviz.sim.robots`.
"""

from __future__ import annotations

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
        b_lo, b_hi = self.b_range_s
        return (
            f"asks for a CoM height of {height:.3f} m; {self.name} walks at "
            f"{lo:.3f}–{hi:.3f} m, i.e. b from {b_lo:.3f} to {b_hi:.3f} s"
        )


SPECS: dict[str, RobotSpec] = {
    "talos": RobotSpec(
        name="talos",
        mass_kg=90.27,
        com_height_m=0.877,
        foot_length_m=0.21,
        foot_width_m=0.13,
        foot_spacing_m=0.17,
        max_step_length_m=0.45,
        max_step_width_m=0.50,
        min_step_width_m=0.14,
        max_step_height_m=0.15,
        # 2 × 0.45 m (behind the stance foot → in front of it) in 0.5 s
        max_swing_speed_m_s=1.8,
        # CoM above the soles in a squat with upright torso and flat feet (hip = ankle = −knee/2):
        # 0.877 m in half-sitting (knee 0.86 rad); straight legs 0.931 m; 0.90 m at knee ≈ 0.65,
        # 0.72 m at knee ≈ 1.75 rad (ankle −0.87, limit −1.31)
        min_com_height_m=0.72,
        max_com_height_m=0.90,
        bodies={
            "torso": "torso_2_link",
            "pelvis": "base_link",
            "left_thigh": "leg_left_3_link",
            "right_thigh": "leg_right_3_link",
        },
        # hip 0.129 m below the CoM, ankle 0.107 m above the sole: 0.900 − 0.236
        leg_length_m=0.664,
    ),
    "g1": RobotSpec(
        name="g1",
        mass_kg=33.34,
        com_height_m=0.670,  # above the sole plane of the foot spheres (bottoms 0.035 m below ankle)
        foot_length_m=0.17,
        foot_width_m=0.06,
        foot_spacing_m=0.237,  # sole centres with hip roll 0 in the URDF
        max_step_length_m=0.30,
        max_step_width_m=0.40,
        min_step_width_m=0.10,
        max_step_height_m=0.10,
        # 2 × 0.30 m in 0.4 s
        max_swing_speed_m_s=1.5,
        # 0.670 m with knee 0.669 rad; straight legs 0.698 m; 0.68 m at knee ≈ 0.55,
        # 0.56 m at knee ≈ 1.52 rad (ankle −0.76, limit −0.87)
        min_com_height_m=0.56,
        max_com_height_m=0.68,
        bodies={
            "torso": "torso_link",
            "pelvis": "pelvis",
            "left_thigh": "left_hip_yaw_link",
            "right_thigh": "right_hip_yaw_link",
        },
        # hip roll 0.046 m below the CoM, ankle pitch 0.052 m above the sole: 0.680 − 0.098
        leg_length_m=0.582,
    ),
}

ROBOT_NAMES = tuple(SPECS)


def get_spec(name: str) -> RobotSpec:
    """The spec of robot ``name``; ValueError naming the allowed robots otherwise."""
    try:
        return SPECS[name]
    except KeyError:
        raise ValueError(
            f"robot.model = {name!r}: unknown robot; allowed: {', '.join(ROBOT_NAMES)}"
        ) from None
