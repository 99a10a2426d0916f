"""Footstep generation: the standing feet, a plan-mode walk and the receding horizon.

Steps advance ``step_length`` along a heading that turns ``turn`` per step; the sole centres sit
``step_width``/2 either side of the midline.
"""

from __future__ import annotations

import math

import numpy as np

from dcmviz.config import GaitSection
from dcmviz.state import OTHER, SIDE_SIGN, Footstep


def _heading_offset(yaw: float, side: str, width: float) -> np.ndarray:
    s = SIDE_SIGN[side] * 0.5 * width
    return np.array([-math.sin(yaw) * s, math.cos(yaw) * s, 0.0])


def initial_feet(gait: GaitSection) -> dict[str, Footstep]:
    """Standing feet at t = 0: sole centres at (0, ±step_width/2, 0)."""
    return {
        side: Footstep(side, _heading_offset(0.0, side, gait.step_width), 0.0)
        for side in ("left", "right")
    }


def generated_step(gait: GaitSection, k: int, *, closing: bool) -> Footstep:
    """Footstep k ≥ 1 of the generated plan (midline advances step_length along heading k·turn).

    With ``closing`` the step lands beside the previous one (the plan's last step).
    """
    side = gait.first_swing if k % 2 == 1 else OTHER[gait.first_swing]
    m = np.zeros(3)
    yaw = 0.0
    last = k - 1 if closing else k
    for j in range(1, last + 1):
        yaw = j * gait.turn
        m = m + np.array(
            [gait.step_length * math.cos(yaw), gait.step_length * math.sin(yaw), gait.step_height]
        )
    return Footstep(side, m + _heading_offset(yaw, side, gait.step_width), yaw)


def plan_footsteps(gait: GaitSection) -> tuple[dict[str, Footstep], tuple[Footstep, ...]]:
    """Initial feet and the footsteps of a plan-mode walk (explicit ones if given)."""
    feet = initial_feet(gait)
    if gait.footsteps is not None:
        steps = tuple(
            Footstep(f.side, np.array(f.position, dtype=float), f.yaw) for f in gait.footsteps
        )
    else:
        n = gait.n_steps
        steps = tuple(generated_step(gait, k, closing=(k == n and n > 1)) for k in range(1, n + 1))
    return feet, steps


def horizon_steps(
    gait: GaitSection, start_feet: dict[str, Footstep], next_side: str, count: int
) -> tuple[Footstep, ...]:
    """``count`` generated footsteps continuing from ``start_feet`` (continuous mode).

    Each step is placed relative to the midline of the two current feet, heading + turn, so an
    adjusted (really landed) foot shifts the walk only through the stance it leaves behind.
    """
    feet = dict(start_feet)
    side = next_side
    out = []
    for _ in range(count):
        stance = feet[OTHER[side]]
        yaw = stance.yaw + gait.turn
        mid = stance.position - _heading_offset(stance.yaw, stance.side, gait.step_width)
        mid = mid + np.array(
            [gait.step_length * math.cos(yaw), gait.step_length * math.sin(yaw), gait.step_height]
        )
        step = Footstep(side, mid + _heading_offset(yaw, side, gait.step_width), yaw)
        out.append(step)
        feet[side] = step
        side = OTHER[side]
    return tuple(out)
