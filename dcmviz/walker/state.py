"""What flows between the walker (§III, backend-independent) and a backend (point mass or humanoid).

A backend measures a :class:`MeasuredState` each control tick; the walker answers with a
:class:`WalkerCommand`.  Forces are in N, positions in m, world frame, z up, x forward.

Force conventions (paper eq. 4 and §III-C):

* ``com_force`` is the desired *total* force on the CoM, ``m/b² (x - v)`` with ``v`` the
  commanded VRP (eq. 4); ``m ẍ = com_force`` if everything is realised.
* ``contact_force`` is what the feet must push with: the total force minus gravity minus the
  estimated perturbation, ``com_force + m g e_z - f_hat``.  A backend realises this (the point mass
  directly, the humanoid through its whole-body QP) and does not need to know about the observer.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dcmviz.gait.plan import GaitPlan
from dcmviz.gait.walk import StepRecord


@dataclass(frozen=True)
class FootTarget:
    """Desired sole pose and its derivatives (sole frame origin; yaw about world z)."""

    position: np.ndarray  # (3,) m
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))  # (3,) m/s
    acceleration: np.ndarray = field(default_factory=lambda: np.zeros(3))  # (3,) m/s²
    yaw: float = 0.0  # rad
    yaw_rate: float = 0.0  # rad/s


@dataclass(frozen=True)
class MeasuredState:
    """What a backend measures each tick."""

    t: float  # s, simulation time
    com: np.ndarray  # (3,) m
    com_velocity: np.ndarray  # (3,) m/s
    feet: dict[str, np.ndarray]  # side -> (3,) sole position, m
    feet_yaw: dict[str, float]  # side -> rad
    in_contact: dict[str, bool]  # side -> measured contact
    mass: float  # kg
    # the contact force (N, sum over feet) the backend actually commanded after its own limits
    # (support polygon, friction, torque limits): the "known force" of the observer, eq. (42).
    # None: the walker uses the force it asked for.
    applied_contact_force: np.ndarray | None = None
    # estimated external moment about the CoM (N·m, world), e.g. a push above the CoM; None when
    # the backend has no such estimate (the point mass: every force acts at the CoM)
    external_moment: np.ndarray | None = None

    @property
    def momentum(self) -> np.ndarray:
        """Linear momentum m ẋ (N·s), the p of eq. (43)."""
        return self.mass * self.com_velocity

    def dcm(self, b: float) -> np.ndarray:
        """ξ = x + b ẋ, eq. (1)."""
        return self.com + b * self.com_velocity


@dataclass(frozen=True)
class WalkerCommand:
    """What the walker asks of a backend for one tick."""

    t: float
    # contact schedule: desired contact state of each foot this tick
    support: dict[str, bool]  # side -> the foot bears weight
    feet: dict[str, FootTarget]  # side -> where the sole should be (stance: where it stands)
    swing_side: str | None  # the foot in the air, if any
    # forces (see module docstring)
    com_force: np.ndarray  # (3,) N, eq. (4)
    contact_force: np.ndarray  # (3,) N, sum of desired contact forces
    # references, for plots and recordings
    xi: np.ndarray  # measured DCM, eq. (1)
    xi_ref: np.ndarray  # nominal DCM reference (shifted, eq. 48, when the observer is on)
    xi_adj: np.ndarray  # adjusted DCM reference (eqs. 33, 49)
    v_ref: np.ndarray  # nominal VRP reference (eq. 47)
    v_cmd: np.ndarray  # commanded VRP, eq. (24) or (40)/(41)
    f_hat: np.ndarray  # estimated perturbation force, eq. (45)
    v_cmd_rate: np.ndarray | None = None  # (3,) m/s, feed-forward rate of v_cmd (= v̇_ref)
    phase: int = 0  # current transition phase index (0-based)
    swing_progress: float = 0.0  # 0..1 through single support (0 outside it)
    step_index: int = 0  # index of the step being taken (0 = first step), -1 while standing
    done: bool = False  # the plan ended and the robot stands
    legs_may_cross: bool = False  # the recovery may cross the legs: the whole-body QP keeps them
    # apart (dcmviz.sim.wbc.legs); strategies that keep each leg on its side need no such rows


@dataclass(frozen=True)
class WalkerStatus:
    """What the walker publishes after a tick: the plan walked and the recovery's footholds."""

    plan: GaitPlan  # walked now (committed adjustments; continuous: the receding horizon)
    plan_version: int  # changes whenever the walked plan does (reset, touchdown, re-timing)
    nominal_plan: GaitPlan  # before any adjustment (continuous: as of the last replanning)
    adjusted: tuple[int, np.ndarray] | None  # footstep being adjusted now and where it lands
    following: tuple[int, np.ndarray] | None  # the footstep after it and where it lands
    records: tuple[StepRecord, ...]  # footsteps landed, in order
    steps_completed: int
    next_step_index: int  # index into plan.steps of the first footstep not yet landed
    # (n, 3) the swinging sole's path still to go (SwingTrajectory.path); None on both feet
    swing_path: np.ndarray | None = None
