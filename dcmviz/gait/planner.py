"""The one plan builder: a preset's walk as :class:`~dcmviz.gait.plan.GaitPlan` s.

:class:`Planner` builds the first plan of a walk (standing → the footsteps → standing in plan
mode, Fig. 1; the first receding horizon in continuous mode) and, in continuous mode, the plan
after every touchdown (the horizon replanned from where the feet stand).  The walker walks its
plans and the dashboard previews the same first plan; :func:`plan_from_config` is that first
plan from the preset alone (feet at their standing places).
"""

from __future__ import annotations

import math

import numpy as np

from dcmviz.config import Config, DcmSection, GaitSection
from dcmviz.gait.footsteps import horizon_steps, initial_feet, on_terrain, plan_footsteps
from dcmviz.gait.plan import GaitPlan, build_plan, timing_of
from dcmviz.gait.terrain import Terrain, terrain_of
from dcmviz.robots.feet import OTHER, Footstep
from dcmviz.robots.spec import RobotSpec

HORIZON_STEPS = 4  # continuous mode: at least this many footsteps previewed ahead
HORIZON_TIME_CONSTANTS = 15.0  # ... and at least 15 b of walking before the terminal constraint


def horizon_count(gait: GaitSection, b: float) -> int:
    """Footsteps in the continuous mode's receding horizon.

    The terminal constraint (eq. 17) at the horizon's end, and the footstep each replanning
    adds there, reach back to the present through e^(−T_h/b) (eq. 15); with T_h ≥ 15 b that is
    below 1e-6, so a replanning moves ξ_ref by less than 1e-6 of a step instead of millimetres
    to centimetres with a fixed count of 4 steps (fast steps, large b).
    """
    per_step = gait.t_ss + gait.t_ds
    return max(HORIZON_STEPS, math.ceil(HORIZON_TIME_CONSTANTS * b / per_step))


class Planner:
    """Builds the plans of one walk from the preset's gait and DCM settings, for one robot
    (whose legs set the VRP heights, :mod:`dcmviz.gait.height`) on one terrain."""

    def __init__(
        self, gait: GaitSection, dcm: DcmSection, spec: RobotSpec, terrain: Terrain
    ) -> None:
        self.gait, self.spec, self.terrain = gait, spec, terrain
        self.b, self.order = dcm.b, dcm.order
        self.timing = timing_of(gait)

    @classmethod
    def of(cls, config: Config, spec: RobotSpec) -> Planner:
        return cls(config.gait, config.dcm, spec, terrain_of(config.terrain))

    @property
    def horizon(self) -> int:
        """Footsteps previewed ahead in continuous mode (:func:`horizon_count`)."""
        return horizon_count(self.gait, self.b)

    def first(
        self,
        start_feet: dict[str, Footstep] | None = None,
        *,
        t0: float = 0.0,
        start_com: np.ndarray | None = None,
    ) -> GaitPlan:
        """The walk's first plan, standing at ``start_feet`` (default: the preset's standing
        feet on the ground) with the CoM at rest at ``start_com`` (default: Δz_vrp above the
        middle of the feet): the whole walk in plan mode, the first horizon in continuous mode."""
        gait = self.gait
        if start_feet is None:
            feet = initial_feet(gait)
            start_feet = dict(
                zip(feet, on_terrain(tuple(feet.values()), self.terrain), strict=True)
            )
        if gait.mode == "plan":
            _, steps = plan_footsteps(gait)
        else:
            steps = horizon_steps(gait, start_feet, gait.first_swing, self.horizon)
        return build_plan(
            start_feet,
            on_terrain(steps, self.terrain),
            self.timing,
            self.b,
            self.order,
            t0=t0,
            start_com=start_com,
            spec=self.spec,
        )

    def after_touchdown(
        self,
        placed: dict[str, Footstep],
        nominal_feet: dict[str, Footstep],
        landed: str,
        t0: float,
    ) -> GaitPlan:
        """Continuous mode: the horizon replanned at the touchdown of foot ``landed`` (global
        time ``t0``), from the feet where they stand (``placed``); the next footsteps continue
        the nominal walk (``nominal_feet``: where the feet would stand without adjustment), so
        an adjustment shifts the walk only through the stance it leaves behind."""
        steps = horizon_steps(self.gait, nominal_feet, OTHER[landed], self.horizon)
        return build_plan(
            dict(placed),
            on_terrain(steps, self.terrain),
            self.timing,
            self.b,
            self.order,
            start="transfer",
            landed=landed,
            t0=t0,
            spec=self.spec,
            nominal_feet=nominal_feet,
        )


def plan_from_config(
    config: Config,
    start_feet: dict[str, Footstep] | None = None,
    start_com: np.ndarray | None = None,
    *,
    spec: RobotSpec | None = None,
) -> GaitPlan:
    """The first plan of a preset's walk (:meth:`Planner.first`) for its robot (``spec``, else
    the one ``robot.model`` names)."""
    if spec is None:
        from dcmviz.robots.robot import load_robot

        spec = load_robot(config.robot.model).spec
    return Planner.of(config, spec).first(start_feet, start_com=start_com)
