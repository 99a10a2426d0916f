"""Reach of a robot's legs: is a footstep reachable from the stance foot, and the nearest one that is.

Pure geometry in the stance foot's frame (x along its yaw, y to the side of the swinging foot).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from dcmviz.robots.feet import OTHER, SIDE_SIGN, Footstep
from dcmviz.robots.spec import RobotSpec


def generated_step_offset(
    step_length: float, step_width: float, turn: float
) -> tuple[float, float]:
    """(Δx, lateral) in m of a generated footstep in its stance foot's frame (yaw + ``turn``).

    A turn pivots about the inner foot: with Δx = w tan(|Δψ|/2) and lateral w both feet sit at
    the same (Δx, ±w) in each other's frames, so in place (step_length 0) the inner foot only
    turns and the outer one swings around it; ``step_length`` adds along the stance foot's x.
    The width measured in the stance frame is always ``step_width``.  Straight: (L, w).
    """
    return step_length + step_width * math.tan(0.5 * abs(turn)), step_width


def check_reachable(spec: RobotSpec, gait: Any) -> None:
    """ValueError naming the first footstep of a preset's ``gait`` section out of the robot's reach.

    Generated footsteps are checked by their parameters (their offset in the stance foot's frame,
    :func:`generated_step_offset`); explicit ones one by one, relative to the stance foot (the
    first from the standing feet at (0, ±step_width/2, 0)).
    """
    if gait.footsteps is None:
        L, w, h = abs(gait.step_length), gait.step_width, abs(gait.step_height)
        for key, value, limit in (
            ("step_length", L, spec.max_step_length_m),
            ("step_width", w, spec.max_step_width_m),
            ("step_height", h, spec.max_step_height_m),
        ):
            if value > limit + 1e-12:
                raise ValueError(
                    f"gait.{key} = {getattr(gait, key)}: out of {spec.name}'s reach; "
                    f"allowed |{key}| ≤ {limit} m"
                )
        dx, _ = generated_step_offset(gait.step_length, w, gait.turn)
        if abs(dx) > spec.max_step_length_m + 1e-12:
            raise ValueError(
                f"gait.step_length = {gait.step_length}, gait.turn = {gait.turn}: turning about "
                f"the inner foot puts each step {dx:.3f} m ahead of the stance foot "
                f"(step_length + step_width·tan(|turn|/2)), out of {spec.name}'s reach; allowed "
                f"≤ {spec.max_step_length_m} m"
            )
        if abs(gait.turn) > spec.max_turn_rad + 1e-12:
            raise ValueError(
                f"gait.turn = {gait.turn}: {spec.name}'s hip yaw joints cannot turn that far per "
                f"step; allowed |turn| ≤ {spec.max_turn_rad:.3f} rad"
            )
        if w < spec.min_step_width_m:
            raise ValueError(
                f"gait.step_width = {w}: the feet of {spec.name} collide; allowed "
                f"≥ {spec.min_step_width_m} m"
            )
        return
    current = {
        side: Footstep(side, np.array([0.0, SIDE_SIGN[side] * 0.5 * gait.step_width, 0.0]))
        for side in SIDE_SIGN
    }
    for i, entry in enumerate(gait.footsteps):
        step = Footstep(entry.side, np.array(entry.position, dtype=float), entry.yaw)
        problem = reach_problem(spec, current[OTHER[step.side]], step)
        if problem:
            raise ValueError(f"gait.footsteps[{i}] = {tuple(step.position.tolist())}: {problem}")
        current[step.side] = step


def reach_problem(spec: RobotSpec, stance: Footstep, step: Footstep) -> str:
    """'' if ``step`` is reachable from ``stance``, else why not (stance-foot frame)."""
    d = step.position - stance.position
    c, s = math.cos(stance.yaw), math.sin(stance.yaw)
    dx, dy = c * d[0] + s * d[1], -s * d[0] + c * d[1]
    lateral = SIDE_SIGN[step.side] * dy  # > 0 on the correct side
    if abs(dx) > spec.max_step_length_m + 1e-9:
        return (
            f"out of {spec.name}'s reach from the {stance.side} foot: |Δx| = {abs(dx):.3f} m, "
            f"allowed ≤ {spec.max_step_length_m} m"
        )
    if lateral > spec.max_step_width_m + 1e-9:
        return (
            f"out of {spec.name}'s reach from the {stance.side} foot: width {lateral:.3f} m, "
            f"allowed ≤ {spec.max_step_width_m} m"
        )
    if lateral < spec.min_step_width_m - 1e-9:
        return (
            f"too close to (or across) the {stance.side} foot: width {lateral:.3f} m, "
            f"allowed ≥ {spec.min_step_width_m} m"
        )
    if abs(d[2]) > spec.max_step_height_m + 1e-9:
        return (
            f"height change {d[2]:.3f} m out of {spec.name}'s reach, allowed "
            f"|Δz| ≤ {spec.max_step_height_m} m"
        )
    return ""


def clamp_to_reach(
    spec: RobotSpec, stance: Footstep, step: Footstep, nominal: np.ndarray, max_adjustment: float
) -> np.ndarray:
    """Project an adjusted footstep position onto what is allowed (horizontal only).

    The adjustment relative to ``nominal`` is limited to ``max_adjustment`` (m), then the result is
    clipped to the reach box of the stance foot (no leg crossing, eq. 32 is kept where possible).
    """
    nx, ny, nz = np.asarray(nominal, dtype=float).tolist()
    px, py = float(step.position[0]), float(step.position[1])
    x, y = clamp_xy_to_reach(spec, stance, step.side, px, py, nx, ny, max_adjustment)
    return np.array([x, y, nz])


def clamp_xy_to_reach(
    spec: RobotSpec,
    stance: Footstep,
    side: str,
    px: float,
    py: float,
    nx: float,
    ny: float,
    max_adjustment: float,
) -> tuple[float, float]:
    """:func:`clamp_to_reach` of the ``side`` foot's footstep at (px, py) with its nominal at
    (nx, ny), in floats: (x, y) of the result (a recovery asks this every tick; on 2-vectors
    numpy's per-call overhead would be most of the cost)."""
    ddx, ddy = px - nx, py - ny
    n = math.hypot(ddx, ddy)
    if n > max_adjustment:
        scale = max_adjustment / n if n > 0 else 0.0
        ddx, ddy = ddx * scale, ddy * scale
    px, py = nx + ddx, ny + ddy
    c, s = math.cos(stance.yaw), math.sin(stance.yaw)
    sx, sy = float(stance.position[0]), float(stance.position[1])
    d0, d1 = px - sx, py - sy
    dx, dy = c * d0 + s * d1, -s * d0 + c * d1
    sign = SIDE_SIGN[side]
    dx = min(max(dx, -spec.max_step_length_m), spec.max_step_length_m)
    lateral = min(max(sign * dy, spec.min_step_width_m), spec.max_step_width_m)
    dy = sign * lateral
    return sx + c * dx - s * dy, sy + s * dx + c * dy
