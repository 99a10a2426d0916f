"""Robot facts for planning and validation (no MuJoCo, no Pinocchio): size, reach, feet, bodies.

The models themselves (URDF → Pinocchio + MuJoCo) are built in :mod:`dcmviz.sim.robots`.
"""

from dcmviz.robots.reach import clamp_to_reach, reach_problem
from dcmviz.robots.spec import ROBOT_NAMES, SPECS, RobotSpec, get_spec

__all__ = ["ROBOT_NAMES", "SPECS", "RobotSpec", "clamp_to_reach", "get_spec", "reach_problem"]
