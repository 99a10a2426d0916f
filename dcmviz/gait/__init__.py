"""Gait planning: footsteps (generation, receding horizon), the plan (VRP waypoints, durations,
contact schedule, closed-form preview) and swing-foot paths."""

from dcmviz.gait.feasibility import PlanWarning, check_plan
from dcmviz.gait.footsteps import (
    generated_step,
    horizon_steps,
    initial_feet,
    on_terrain,
    plan_footsteps,
)
from dcmviz.gait.plan import (
    START_SPLIT,
    ContactState,
    GaitPlan,
    Timing,
    build_plan,
    plan_from_config,
    timing_of,
)
from dcmviz.gait.swing import RETARGET_FREEZE, SWING_HEIGHT_M, SwingTrajectory
from dcmviz.robots.reach import clamp_to_reach, reach_problem
from dcmviz.state import OTHER, SIDE_SIGN, Footstep

__all__ = [
    "OTHER",
    "RETARGET_FREEZE",
    "SIDE_SIGN",
    "START_SPLIT",
    "SWING_HEIGHT_M",
    "ContactState",
    "Footstep",
    "GaitPlan",
    "SwingTrajectory",
    "Timing",
    "PlanWarning",
    "build_plan",
    "check_plan",
    "clamp_to_reach",
    "generated_step",
    "horizon_steps",
    "initial_feet",
    "on_terrain",
    "plan_footsteps",
    "plan_from_config",
    "reach_problem",
    "timing_of",
]
