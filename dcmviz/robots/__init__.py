"""Robots as files, each built once into one :class:`Robot` (:func:`load_robot`, the only place a
robot is looked up by name).

The robot file schema (:mod:`.file`), the model text edited (:mod:`.urdf`, :mod:`.mjcf`), the
standing posture (:mod:`.posture`), the derived numbers (:mod:`.derive`) and the Pinocchio model
that carries them (:mod:`.model`); the planning facts (:mod:`.spec`), the feet and footsteps
(:mod:`.feet`), the reach (:mod:`.reach`); the MuJoCo model (:mod:`.mujoco_model`) and the visual
model (:mod:`.visual`).  ``python -m dcmviz.robots NAME|PATH`` prints what a robot file derives
(:mod:`.report`).
"""

from dcmviz.robots.feet import OTHER, SIDE_SIGN, SIDES, Footstep
from dcmviz.robots.file import BUILTIN_ROBOTS, RobotFileError, example_robot_data_dir
from dcmviz.robots.reach import clamp_to_reach, reach_problem
from dcmviz.robots.robot import Robot, load_robot
from dcmviz.robots.spec import RobotSpec

__all__ = [
    "BUILTIN_ROBOTS",
    "OTHER",
    "SIDES",
    "SIDE_SIGN",
    "Footstep",
    "Robot",
    "RobotFileError",
    "RobotSpec",
    "clamp_to_reach",
    "example_robot_data_dir",
    "load_robot",
    "reach_problem",
]
