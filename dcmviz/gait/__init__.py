"""Gait planning: terrain, footsteps (generation, receding horizon), the plan (VRP waypoints,
durations, contact schedule, closed-form preview) built by one :class:`Planner`, swing-foot paths,
step timing, feasibility, and a :class:`Walk` along the plans (feet placed, swing, landings)."""

from dcmviz.gait.feasibility import PlanWarning, check_plan
from dcmviz.gait.footsteps import (
    generated_step,
    horizon_steps,
    initial_feet,
    on_terrain,
    plan_footsteps,
)
from dcmviz.gait.plan import START_SPLIT, ContactState, GaitPlan, Timing, build_plan, timing_of
from dcmviz.gait.planner import Planner, horizon_count, plan_from_config
from dcmviz.gait.swing import RETARGET_FREEZE, SWING_HEIGHT_M, SwingTrajectory
from dcmviz.gait.walk import StepRecord, Walk
from dcmviz.robots.feet import OTHER, SIDE_SIGN, Footstep
from dcmviz.robots.reach import clamp_to_reach, reach_problem

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
    "Planner",
    "StepRecord",
    "Walk",
    "horizon_count",
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
