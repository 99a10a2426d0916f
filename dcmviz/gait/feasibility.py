"""Feasibility of a plan before walking it: a pure check that returns warnings, never raises.

:func:`check_plan` looks at a :class:`~dcmviz.gait.plan.GaitPlan` with the robot's facts and
says what the robot cannot do, naming the setting or the footstep and the limit:

* support: the ground point of every VRP waypoint (waypoint − Δz_vrp e_z, i.e. its x-y), the D2
  waypoint among them, lies at least :data:`SUPPORT_MARGIN_M` inside the support polygon of the
  feet in contact at that instant (the sole rectangle of the stance foot while one foot swings,
  the convex hull of both soles otherwise; a waypoint between a double- and a single-support
  phase must be inside the single support);
* reach: every footstep is inside the reach of its stance foot, measured in the stance foot's
  frame (:func:`dcmviz.robots.reach.reach_problem`), and its sole rectangle (length × width,
  yaw) does not intersect the stance foot's;
* swing speed: lift-off → touchdown distance (horizontal) / T_ss ≤ ``spec.max_swing_speed_m_s``;
* CoM height: Δz_vrp = g b² inside the robot's range (eq. 1; the preset validation refuses such a
  b, a plan built otherwise is still warned about), and whether the legs span every stride at
  that height (:mod:`dcmviz.gait.height`: a plan walks lower where they cannot, and says so).

Footsteps are 1-based in messages ("footstep 3"), 0-based in :attr:`PlanWarning.step` (an index
into ``plan.steps``), like waypoints (``plan.waypoints``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from dcmviz.config import Config
from dcmviz.gait.height import REACH_FRACTION, leg_span_m, step_heights
from dcmviz.gait.plan import GaitPlan
from dcmviz.gait.terrain import terrain_of
from dcmviz.robots.feet import SIDE_SIGN, Footstep
from dcmviz.robots.geometry import (
    convex_hull,
    hull_depth,
    project_to_polygon,
    rectangle_gap,
    soles_corners,
)
from dcmviz.robots.reach import reach_problem
from dcmviz.robots.spec import RobotSpec

SUPPORT_MARGIN_M = 0.01  # a VRP waypoint's ground point must be ≥ 1 cm inside the support polygon
# a plan that walks lower than Δz_vrp by more than this (m) says so: within it the CoM height is
# within what the humanoid tracks anyway (the envelope's vertical limit is 2 cm)
HEIGHT_TOLERANCE_M = 0.01
# a plan starts from the measured feet, which settle a few mm into MuJoCo's soft contact: a
# 0.15 m stair measured from them is 0.151 m high; step heights are judged with this slack (m)
SINK_TOLERANCE_M = 0.005


@dataclass(frozen=True)
class PlanWarning:
    """One thing the robot cannot do in a plan; ``str()`` is the message."""

    message: str
    setting: str | None = None  # the preset key to change, e.g. "gait.t_start"
    step: int | None = None  # 0-based index into plan.steps of the offending footstep
    waypoint: int | None = None  # 0-based index into plan.waypoints

    def __str__(self) -> str:
        return self.message


def check_plan(
    plan: GaitPlan, spec: RobotSpec, config: Config, crossover: Any = None
) -> list[PlanWarning]:
    """Warnings for everything in ``plan`` outside what ``spec``'s robot can do (empty: feasible).

    ``config`` names the settings the plan came from (generated or explicit footsteps, timing).
    ``crossover``: the robot's :class:`~dcmviz.robots.crossover.CrossoverRegion`, or a callable
    giving it (asked only for a plan with a footstep across its stance foot): a footstep inside
    it is a crossed stance, not out of reach, unless the footstep before it crossed too (the
    legs must uncross first).
    """
    warnings: list[PlanWarning] = []
    problem = spec.height_problem(plan.b)
    if problem:
        warnings.append(PlanWarning(f"dcm.b = {plan.b:.3f}: {problem}", "dcm.b"))
    else:
        warnings += _height_warnings(plan, spec)
    stances = [plan.stance_for(k) for k in range(len(plan.steps))]
    warnings += _support_warnings(plan, spec, stances)
    warnings += _step_warnings(plan, spec, config, stances, crossover)
    warnings += _edge_warnings(plan, spec, config)
    return warnings


def _edge_warnings(plan: GaitPlan, spec: RobotSpec, config: Config) -> list[PlanWarning]:
    """A footstep whose sole lies across a tread's edge (the ground under its corners at two
    heights): the sole cannot land flat, and its swing cannot clear an edge it lands on."""
    terrain = terrain_of(config.terrain)
    if terrain.flat or not plan.steps:
        return []
    pos = np.array([s.position for s in plan.steps])
    yaw = np.array([s.yaw for s in plan.steps])
    corners = soles_corners(pos, yaw, spec.foot_length_m, spec.foot_width_m)  # (n, 4, 2)
    heights = terrain.sole_heights(corners)  # (n, 4): unequal under a sole straddle an edge
    explicit = _explicit(plan, config)
    generated = "terrain.stairs.start" if config.terrain.stairs is not None else "gait.step_length"
    out = []
    for k in np.nonzero(np.ptp(heights, axis=1) > 1e-6)[0]:
        k = int(k)
        low, high = float(heights[k].min()), float(heights[k].max())
        key = f"gait.footsteps[{k}]" if explicit else generated
        out.append(PlanWarning(
            f"footstep {k + 1}: its sole lies across an edge (the ground under it at {low:.3f} and "
            f"{high:.3f} m) and cannot land flat; move {key} so that every sole lies on one "
            "tread", key, k,
        ))  # fmt: skip
    return out


def _height_warnings(plan: GaitPlan, spec: RobotSpec) -> list[PlanWarning]:
    """One warning when the legs cannot span a stride at Δz_vrp and the plan walks lower.

    On terrain the legs also reach down half of each rise, so stairs walk lower too.
    """
    if not plan.steps:
        return []
    heights = step_heights(spec, plan.dz_vrp, plan.start_feet, plan.steps)
    k = int(np.argmin(heights))
    if heights[k] >= plan.dz_vrp - HEIGHT_TOLERANCE_M:
        return []
    span = leg_span_m(spec, plan.stance_for(k), plan.steps[k])
    lo, hi = spec.com_height_range_m
    if heights[k] < lo:  # no walking height at all: say so, not a height the robot never has
        return [
            PlanWarning(
                f"footstep {k + 1} lies {span / REACH_FRACTION:.3f} m from its stance foot: "
                f"with the feet that far apart {spec.name}'s legs cannot hold the CoM at any "
                f"height it walks at ({lo:.2f}–{hi:.2f} m); shorter steps (gait.step_length, "
                f"gait.step_width) keep it",
                "gait.step_length",
                k,
            )
        ]
    return [
        PlanWarning(
            f"dcm.b = {plan.b:.3f} asks for a CoM height of {plan.dz_vrp:.3f} m, but with "
            f"footstep {k + 1} {span / REACH_FRACTION:.3f} m from its stance foot "
            f"{spec.name}'s legs reach only {heights[k]:.3f} m high: the walk lowers the CoM "
            f"by {plan.dz_vrp - heights[k]:.3f} m while the feet are apart (a smaller dcm.b or "
            f"shorter steps keep it)",
            "dcm.b",
            k,
        )
    ]


# ---------------------------------------------------------------------------------------------
# support polygon


def _phase_feet(plan: GaitPlan, stances: list[Footstep]) -> list[tuple[Footstep, ...]]:
    """The feet in contact during each phase of the plan."""
    both = (plan.start_feet["left"], plan.start_feet["right"])
    feet = []
    for kind, k in zip(plan.phase_kind, plan.phase_step, strict=True):
        if kind == "ss":
            feet.append((stances[k],))
        elif k < 0:  # start_a, start_b, or the double support a transfer plan begins with
            feet.append(both)
        else:  # ds, stop: the foot that just landed and the one it landed beside
            feet.append((plan.steps[k], stances[k]))
    return feet


def _support_warnings(
    plan: GaitPlan, spec: RobotSpec, stances: list[Footstep]
) -> list[PlanWarning]:
    phase_feet = _phase_feet(plan, stances)
    n_phase = len(phase_feet)
    wp = plan.waypoints
    # waypoint i ends phase i − 1 and starts phase i: it must be inside the smaller support
    feet_at: list[tuple[Footstep, ...]] = []
    for i in range(len(wp)):
        adjacent = [phase_feet[p] for p in (i - 1, i) if 0 <= p < n_phase]
        feet_at.append(min(adjacent, key=len))
    # vertices: the corners of one or two soles, a single sole's repeated (hull_depth pads so)
    contact = [f if len(f) == 2 else (f[0], f[0]) for f in feet_at]
    flat = [foot for pair in contact for foot in pair]
    corners = soles_corners(
        np.array([f.position for f in flat]),
        np.array([f.yaw for f in flat]),
        spec.foot_length_m,
        spec.foot_width_m,
    ).reshape(len(wp), 8, 2)
    depth = hull_depth(wp[:, :2], corners)
    out = []
    for i in np.nonzero(depth < SUPPORT_MARGIN_M - 1e-12)[0]:
        i = int(i)
        polygon = convex_hull(corners[i])
        _, outside = project_to_polygon(wp[i, :2], polygon)
        where = f"{outside:.3f} m outside" if outside > 0.0 else f"only {depth[i]:.3f} m inside"
        feet = feet_at[i]
        support = "both soles" if len(feet) == 2 else f"the {feet[0].side} sole (single support)"
        name, setting, step = _waypoint_name(plan, i)
        out.append(
            PlanWarning(
                f"{name}: the VRP's ground point ({wp[i, 0]:.3f}, {wp[i, 1]:.3f}) m is {where} "
                f"the support polygon of {support}; it must be ≥ {SUPPORT_MARGIN_M:.3f} m inside"
                + (f" (lengthen {setting} or lower dcm.b)" if setting else ""),
                setting,
                step,
                i,
            )
        )
    return out


def _waypoint_name(plan: GaitPlan, i: int) -> tuple[str, str | None, int | None]:
    """How a message names waypoint i, the setting that moves it, and its footstep."""
    if plan.start == "stand" and i == 1:
        return "VRP waypoint 2 (D2, the DCM starts at rest)", "gait.t_start", None
    if plan.start == "stand" and i == 0:
        return "VRP waypoint 1 (standing, D1)", None, None
    n_phase = len(plan.phase_kind)
    k = plan.phase_step[min(i, n_phase - 1)]
    if k < 0 and i > 0:
        k = plan.phase_step[i - 1]
    name = f"VRP waypoint {i + 1}" + (f" (footstep {k + 1})" if k >= 0 else "")
    return name, None, (k if k >= 0 else None)


# ---------------------------------------------------------------------------------------------
# footsteps


def _explicit(plan: GaitPlan, config: Config) -> bool:
    """The plan's steps are the preset's own ``[[gait.footsteps]]`` (same indices)."""
    return (
        config.gait.footsteps is not None
        and config.gait.mode == "plan"
        and plan.start == "stand"
        and len(plan.steps) == len(config.gait.footsteps)
    )


def _step_warnings(
    plan: GaitPlan, spec: RobotSpec, config: Config, stances: list[Footstep], crossover: Any = None
) -> list[PlanWarning]:
    steps = plan.steps
    if not steps:
        return []
    explicit = _explicit(plan, config)

    def setting(k: int, generated: str) -> str:
        return f"gait.footsteps[{k}]" if explicit else generated

    pos = np.array([s.position for s in steps])
    yaw = np.array([s.yaw for s in steps])
    st_pos = np.array([s.position for s in stances])
    st_yaw = np.array([s.yaw for s in stances])
    out: list[PlanWarning] = []

    # reach, in the stance foot's frame (the same limits as reach_problem, which words them)
    d = pos - st_pos
    c, s = np.cos(st_yaw), np.sin(st_yaw)
    dx = c * d[:, 0] + s * d[:, 1]
    lateral = np.array([SIDE_SIGN[step.side] for step in steps]) * (-s * d[:, 0] + c * d[:, 1])
    across = lateral < spec.min_step_width_m - 1e-9
    crossed = np.zeros(len(steps), bool)  # a crossed stance the robot can take
    if across.any() and crossover is not None:
        region = crossover() if callable(crossover) else crossover
        for k in np.nonzero(across)[0]:
            k = int(k)
            follows = k > 0 and bool(crossed[k - 1])
            crossed[k] = not follows and region.contains(float(dx[k]), float(lateral[k]), -0.01)
    bad = (
        (np.abs(dx) > spec.max_step_length_m + 1e-9)
        | (lateral > spec.max_step_width_m + 1e-9)
        | (across & ~crossed)
        | (np.abs(d[:, 2]) > spec.max_step_height_m + SINK_TOLERANCE_M)
    )
    for k in np.nonzero(bad)[0]:
        k = int(k)
        problem = reach_problem(spec, stances[k], steps[k])
        if across[k] and crossover is not None and not problem.startswith("out of"):
            problem += (
                " and outside the crossover region"
                if k == 0 or not crossed[k - 1]
                else "; the footstep before it crossed: the legs must uncross first"
            )
        if abs(dx[k]) > spec.max_step_length_m + 1e-9:
            key = "gait.step_length"
        elif abs(d[k, 2]) > spec.max_step_height_m + SINK_TOLERANCE_M:
            key = "gait.step_height"
        else:
            key = "gait.step_width"
        out.append(PlanWarning(f"footstep {k + 1}: {problem}", setting(k, key), k))

    # soles never intersect
    gap = rectangle_gap(
        soles_corners(pos, yaw, spec.foot_length_m, spec.foot_width_m),
        soles_corners(st_pos, st_yaw, spec.foot_length_m, spec.foot_width_m),
    )
    for k in np.nonzero(gap <= 0.0)[0]:
        k = int(k)
        out.append(
            PlanWarning(
                f"footstep {k + 1}: its sole overlaps the {stances[k].side} sole by "
                f"{-gap[k]:.3f} m ({spec.name}'s soles are {spec.foot_length_m} × "
                f"{spec.foot_width_m} m); the soles must not intersect",
                setting(k, "gait.step_width"),
                k,
            )
        )

    # swing speed: lift-off → touchdown over single support
    lift = np.array([f.position for f in plan.liftoff])
    distance = np.hypot(*(pos[:, :2] - lift[:, :2]).T)
    t_ss = plan.timing.t_ss
    speed = distance / t_ss
    for k in np.nonzero(speed > spec.max_swing_speed_m_s + 1e-9)[0]:
        k = int(k)
        out.append(
            PlanWarning(
                f"footstep {k + 1}: the foot swings {distance[k]:.3f} m in T_ss = {t_ss:.3f} s, "
                f"{speed[k]:.2f} m/s; {spec.name} swings at most {spec.max_swing_speed_m_s} m/s "
                f"(gait.t_ss ≥ {distance[k] / spec.max_swing_speed_m_s:.3f} s for this step)",
                "gait.t_ss",
                k,
            )
        )
    return sorted(out, key=lambda w: w.step)
