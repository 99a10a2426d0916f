"""Torque-level whole-body controller: small tasks and constraints feeding one QP.

One concept per module: :mod:`.gains` (gains, weights, limits), :mod:`.layout` (where q̈ and the
foot wrenches sit in the decision vector), :mod:`.context` (Pinocchio evaluated once per tick),
:mod:`.tasks` (least-squares terms), :mod:`.constraints` (rows of the QP),
:mod:`.moment_observer` (external moment about the CoM) and :mod:`.solver` (the QP, assembled
from whatever tasks and constraints it holds, solved with daqp).
"""

from dcmviz.robots.gains import Gains
from dcmviz.sim.wbc.constraints import (
    Constraint,
    ContactWrenchCone,
    FloatingBaseDynamics,
    JointLimits,
    StanceFoot,
    TorqueLimits,
    TrunkTilt,
)
from dcmviz.sim.wbc.context import Context, Kinematics
from dcmviz.sim.wbc.layout import Layout
from dcmviz.sim.wbc.moment_observer import ForceObserver, MomentObserver
from dcmviz.sim.wbc.solver import Solution, WholeBodyController
from dcmviz.sim.wbc.tasks import (
    AngularMomentumTask,
    BaseOrientationTask,
    ContactForceTask,
    FootTask,
    PostureTask,
    Task,
)

__all__ = [
    "AngularMomentumTask",
    "BaseOrientationTask",
    "Constraint",
    "ContactForceTask",
    "ContactWrenchCone",
    "Context",
    "FloatingBaseDynamics",
    "FootTask",
    "ForceObserver",
    "Gains",
    "JointLimits",
    "Kinematics",
    "Layout",
    "MomentObserver",
    "PostureTask",
    "Solution",
    "StanceFoot",
    "Task",
    "TorqueLimits",
    "TrunkTilt",
    "WholeBodyController",
]
