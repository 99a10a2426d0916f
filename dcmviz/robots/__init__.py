"""Robots as files: the robot file schema (:mod:`.file`), the model and derived numbers
(:mod:`.model`, Pinocchio), planning facts (:mod:`.spec`: size, reach, feet, bodies) and reach.

The MuJoCo model is built in :mod:`dcmviz.sim.robots`.  ``python -m dcmviz.robots NAME|PATH``
prints what a robot file derives.
"""

from dcmviz.robots.file import BUILTIN_ROBOTS, RobotFileError
from dcmviz.robots.reach import clamp_to_reach, reach_problem
from dcmviz.robots.registry import ROBOT_NAMES, SPECS, get_spec
from dcmviz.robots.spec import RobotSpec

__all__ = [
    "BUILTIN_ROBOTS",
    "ROBOT_NAMES",
    "SPECS",
    "RobotFileError",
    "RobotSpec",
    "clamp_to_reach",
    "get_spec",
    "reach_problem",
]
