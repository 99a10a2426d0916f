"""One frozen record per control tick: everything a shell (dashboard, recorder, runner) reads.

The session builds a :class:`Tick` on request after each :meth:`~dcmviz.session.Session.step`;
shells read it and nothing else of the session's insides.  Arrays are copies, safe to keep.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from dcmviz.gait import GaitPlan, StepRecord
from dcmviz.robots import Robot
from dcmviz.robots.feet import Footstep
from dcmviz.robots.pose import RobotPose
from dcmviz.walker.state import MeasuredState, WalkerCommand


@dataclass(frozen=True)
class AppliedPush:
    """An external force acting this tick."""

    body: str  # push target (a key of RobotSpec.bodies)
    force: np.ndarray  # (3,) N, world
    point: np.ndarray  # (3,) m, world: where it acts


@dataclass(frozen=True)
class Pull:
    """A spring pulling a body towards a point (the user's hand, MuJoCo-viewer style)."""

    body: str  # a key of RobotSpec.bodies
    target: np.ndarray  # (3,) m, world: the spring's other end
    stiffness: float  # N/m
    damping: float  # N·s/m
    offset: np.ndarray = field(default_factory=lambda: np.zeros(3))  # grab point − body origin

    def grab(self, body_point: np.ndarray) -> np.ndarray:
        """Where the spring holds the body (m, world) when the body's origin is at
        ``body_point`` (the grab point moves with the body, without turning)."""
        return np.asarray(body_point, float) + self.offset


@dataclass(frozen=True)
class Tick:
    """The state of a walking session after one control tick."""

    index: int  # ticks since the last reset
    t: float  # s, simulation time of the command (the state is measured one tick later)
    robot: Robot  # the robot walked (spec, models, visual), loaded once by the session
    backend: str
    state: MeasuredState  # what the backend measured after the tick
    command: WalkerCommand  # what the walker asked for this tick (ξ, ξ_ref, ξ_adj, v_ref, v_cmd …)
    plan: GaitPlan  # the plan the walker walks (committed adjustments; continuous: the horizon)
    plan_version: int  # changes whenever the walked plan changes (reset, touchdown, replanning)
    nominal_plan: GaitPlan  # the plan as it was when the walk started
    adjusted_index: int  # index into plan.steps of the footstep being adjusted now, -1 if none
    adjusted_step: Footstep | None  # that footstep where it will land (step adjustment, eq. 32)
    recovery_step: Footstep | None  # the footstep after it, where it will land when it takes
    #                                 what the adjusted one cannot (None when it stays nominal)
    realised_steps: tuple[StepRecord, ...]  # footsteps that have landed, in order
    steps_completed: int
    next_step_index: int  # index into plan.steps of the first footstep not yet landed
    pushes: tuple[AppliedPush, ...]  # external forces acting this tick
    f_ext: np.ndarray  # (3,) N, sum of the applied external forces
    f_hat: np.ndarray  # (3,) N, the observer's estimate (eq. 45); zero with the observer off
    pose: RobotPose | None  # humanoid links for drawing; None for the point mass
    fell: bool  # the robot has fallen (this tick or earlier)
    done: bool  # a plan-mode walk has ended and the robot stands
    # measured contacts: (centre of pressure m, force N) per sole in contact (the point mass:
    # one, its contact force); cop: the centre of pressure of them all (None in the air)
    contacts: tuple[tuple[np.ndarray, np.ndarray], ...] = ()
    cop: np.ndarray | None = None
    physics: np.ndarray | None = None  # the backend's physical state (MuJoCo: FULLPHYSICS)
    pull: Pull | None = None  # a spring pull acting this tick (its force is in pushes)
    # (n, 3) the swinging sole's path still to go (None on both feet)
    swing_path: np.ndarray | None = None

    @property
    def dcm_error_m(self) -> float:
        """|ξ − ξ_ref| (m) against the nominal (observer-shifted, eq. 48) reference."""
        e = self.command.xi - self.command.xi_ref
        return math.sqrt(float(e @ e))

    @property
    def support(self) -> str:
        """'left', 'right' or 'double': the feet that bear weight by the contact schedule."""
        sup = self.command.support
        if sup["left"] and sup["right"]:
            return "double"
        return "left" if sup["left"] else "right"

    @property
    def com(self) -> np.ndarray:
        return self.state.com

    def adjusted_steps(self) -> tuple[Footstep, ...]:
        """Footsteps still to come that differ from the nominal plan (the ghosts), the one being
        adjusted right now first."""
        out: list[Footstep] = [s for s in (self.adjusted_step, self.recovery_step) if s]
        plan, nominal = self.plan, self.nominal_plan
        if len(nominal.steps) != len(plan.steps):
            return tuple(out)
        for k in range(self.next_step_index, len(plan.steps)):
            p, q = plan.steps[k].position, nominal.steps[k].position
            pending = self.adjusted_index >= 0 and k in (
                self.adjusted_index,
                self.adjusted_index + 1,
            )
            if not pending and float(np.linalg.norm(p - q)) > 1e-3:
                out.append(plan.steps[k])
        return tuple(out)
