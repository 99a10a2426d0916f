"""The seam between the walker (§III, backend-independent) and a simulated robot.

A backend is anything that measures a :class:`~dcmviz.walker.state.MeasuredState` each control tick and
realises a :class:`~dcmviz.walker.state.WalkerCommand`: the point mass (:mod:`dcmviz.sim.lip`) and the
MuJoCo humanoid (:mod:`dcmviz.sim.mujoco_sim`).  The session talks to it only through this
protocol.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from dcmviz.robots import RobotSpec
from dcmviz.robots.pose import RobotPose
from dcmviz.walker.state import MeasuredState, WalkerCommand


class Backend(Protocol):
    """A simulated robot driven one control tick at a time."""

    name: str  # "lip" | "mujoco"
    spec: RobotSpec
    mass: float  # kg, total mass of the simulated model
    control_dt: float  # s, one control tick

    def reset(self) -> MeasuredState:
        """Stand still on both feet at t = 0 (no external force) and measure."""
        ...

    def step(self, command: WalkerCommand) -> MeasuredState:
        """Realise ``command`` for one control tick and measure."""
        ...

    def set_external_force(self, body: str, force: np.ndarray) -> None:
        """Apply a world-frame force (N) to ``body`` until it is changed."""
        ...

    def fell(self) -> bool:
        """True once the robot has fallen."""
        ...

    def body_position(self, body: str) -> np.ndarray:
        """Where a force on ``body`` acts (m, world): the point mass's CoM, a link's origin."""
        ...

    def robot_pose(self) -> RobotPose | None:
        """The humanoid's pose, or None for a model without links (the point mass)."""
        ...

    def contacts(self) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
        """The measured contacts this tick: (centre of pressure m, force N) of each."""
        ...

    def physics_state(self) -> np.ndarray:
        """The backend's physical state this tick (MuJoCo: mjSTATE_FULLPHYSICS), to compare a
        resumed walk with the original."""
        ...
