"""A walk along its plans: which plan is walked, where the feet stand, the swing in flight and the
footsteps landed.  No DCM control here: the walker (§III) reads and steers a :class:`Walk`.

Each tick :meth:`Walk.clock` advances the contact schedule with the measured feet: at a touchdown
the footstep is committed where the foot really landed (``GaitPlan.with_step``: only that
footstep's waypoints move, so no reference jumps, eqs. 27, 34) and in continuous mode the horizon
is replanned from there (:meth:`~dcmviz.gait.planner.Planner.after_touchdown`); at a lift-off the
swing path starts from where the foot stands.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from dcmviz.gait.plan import ContactState, GaitPlan
from dcmviz.gait.planner import Planner
from dcmviz.gait.swing import SwingTrajectory
from dcmviz.robots.feet import OTHER, SIDES, Footstep

RECORDS_KEPT = 256  # continuous mode: landed footsteps kept (a plan keeps all of its own)


@dataclass(frozen=True)
class StepRecord:
    """A committed footstep: where it landed relative to the nominal plan."""

    t: float  # s, touchdown
    step: int  # footstep counter since the start
    side: str
    position: np.ndarray  # (3,) where it landed
    nominal: np.ndarray  # (3,) where the nominal plan had it
    yaw: float = 0.0  # rad, the footstep's yaw

    @property
    def adjustment(self) -> np.ndarray:
        return self.position - self.nominal


class Walk:
    """The walk of one preset from a standing start: its plans, feet, swing and landings."""

    def __init__(
        self,
        planner: Planner,
        feet: Mapping[str, np.ndarray],
        feet_yaw: Mapping[str, float],
        *,
        t0: float,
        com: np.ndarray,
        plan_version: int = 0,
    ) -> None:
        """Standing where the measured ``feet`` are at time ``t0`` with the CoM at rest at
        ``com``; ``plan_version`` continues the count of an earlier walk."""
        self.planner = planner
        self.continuous = planner.gait.mode == "continuous"
        start = {s: Footstep(s, np.array(feet[s], float), float(feet_yaw[s])) for s in SIDES}
        self.plan: GaitPlan = planner.first(start, t0=t0, start_com=com)
        self.plan_version = plan_version + 1  # changes whenever self.plan does
        self.nominal_plan = self.plan  # before any adjustment (continuous: the last replanning)
        self.placed: dict[str, Footstep] = dict(start)  # where each foot stands (committed)
        self._nominal_feet: dict[str, Footstep] = dict(start)  # continuous mode: nominal cursor
        self.swing: SwingTrajectory | None = None
        self.swing_step: int | None = None
        # grows at touchdowns (continuous mode: the last RECORDS_KEPT); shared by every Tick
        self.records: tuple[StepRecord, ...] = ()
        self.steps_completed = 0

    # -- the clock ------------------------------------------------------------------------------
    def clock(
        self, t: float, feet: Mapping[str, np.ndarray], feet_yaw: Mapping[str, float]
    ) -> tuple[ContactState, bool]:
        """The contact schedule at global time ``t`` after committing a touchdown and starting a
        swing where they happen; True as the second value at a touchdown."""
        contact = self.plan.contact(t)
        touched = False
        if self.swing_step is not None and not (
            contact.kind == "ss" and contact.step == self.swing_step
        ):
            self._touchdown(feet)
            contact = self.plan.contact(t)
            touched = True
        if contact.kind == "ss" and self.swing_step != contact.step:
            self._liftoff(contact.step, feet, feet_yaw)
        return contact, touched

    def done(self, t: float) -> bool:
        """A plan-mode walk has ended (it stands on its final VRP)."""
        return not self.continuous and t >= self.plan.t_end

    # -- steering (the walker's recovery) -------------------------------------------------------
    def retarget_swing(self, t: float, target: np.ndarray) -> None:
        """The swinging foot heads for ``target`` from now on (step adjustment)."""
        self.swing = self.swing.retarget(t, target)

    def retime(self, t: float, plan: GaitPlan) -> None:
        """Walk ``plan``, the same footsteps with other phase durations, from time ``t``; the
        swinging foot keeps its path, re-timed to the new touchdown."""
        self.plan = plan
        self.plan_version += 1
        if self.swing is not None and self.swing_step is not None:
            t_touch = plan.swing_window(self.swing_step)[1]
            self.swing = self.swing.retime(t, t_touch)

    # -- events ---------------------------------------------------------------------------------
    def _liftoff(
        self, k: int, feet: Mapping[str, np.ndarray], feet_yaw: Mapping[str, float]
    ) -> None:
        step = self.plan.steps[k]
        lift = Footstep(step.side, np.array(feet[step.side], float), float(feet_yaw[step.side]))
        t_lift, t_touch = self.plan.swing_window(k)
        spec = self.planner.spec
        self.swing = SwingTrajectory.between(
            t_lift, t_touch, lift, step, terrain=self.planner.terrain,
            sole=(spec.foot_length_m, spec.foot_width_m), stance=self.placed[OTHER[step.side]],
        )  # fmt: skip
        self.swing_step = k

    def _touchdown(self, feet: Mapping[str, np.ndarray]) -> None:
        """Commit the footstep where the foot landed (horizontal), then replan if continuous."""
        k = self.swing_step
        plan = self.plan
        step = plan.steps[k]
        nominal = self.nominal_step_position(k)
        landed = np.array([feet[step.side][0], feet[step.side][1], step.position[2]])
        self.plan = plan.with_step(k, landed)
        self.plan_version += 1
        t_touch = plan.swing_window(k)[1]
        self.placed[step.side] = self.plan.steps[k]
        records = (
            *self.records,
            StepRecord(t_touch, self.steps_completed, step.side, landed, nominal, step.yaw),
        )
        if self.continuous:  # an endless walk: its latest footsteps only
            records = records[-RECORDS_KEPT:]
        self.records = records
        self.steps_completed += 1
        self.swing = None
        self.swing_step = None
        if self.continuous:
            self._nominal_feet[step.side] = Footstep(step.side, nominal, step.yaw)
            self.plan = self.planner.after_touchdown(
                self.placed, self._nominal_feet, step.side, t_touch
            )
            self.nominal_plan = self.plan  # the horizon as generated, before any adjustment

    # -- reading --------------------------------------------------------------------------------
    @property
    def next_step_index(self) -> int:
        """Index into ``plan.steps`` of the first footstep not yet landed (continuous mode
        replans at every touchdown, so its plan starts with the next footstep)."""
        return 0 if self.continuous else self.steps_completed

    def nominal_step_position(self, k: int) -> np.ndarray:
        """Where footstep k of the current plan was before any adjustment (continuous mode: the
        nominal plan is the horizon as generated at the last replanning)."""
        return np.array(self.nominal_plan.steps[k].position, float)

    @property
    def step_adjustments(self) -> list[dict[str, float]]:
        """Committed footsteps that landed away from the nominal plan: {t, step, dx, dy} (m)."""
        return [
            {"t": r.t, "step": r.step, "dx": float(r.adjustment[0]), "dy": float(r.adjustment[1])}
            for r in self.records
        ]
