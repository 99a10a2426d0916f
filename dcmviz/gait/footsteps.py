"""Footstep generation: the standing feet, a plan-mode walk and the receding horizon.

Each step turns ``turn`` (yaw) and lands at (Δx, ±step_width) in its stance foot's frame, with
Δx = step_length + step_width·tan(|turn|/2) (:func:`dcmviz.robots.reach.generated_step_offset`):
a turn pivots about the inner foot, which in place only turns while the outer foot swings around
it, and the feet stay ``step_width`` apart measured in the stance foot's frame, as the robot's reach
is.  Straight walking advances the midline ``step_length`` per step with the sole centres
``step_width``/2 either side of it.
"""

from __future__ import annotations

import math

import numpy as np

from dcmviz.config import GaitSection
from dcmviz.gait.terrain import Terrain
from dcmviz.robots.feet import OTHER, SIDE_SIGN, Footstep
from dcmviz.robots.reach import generated_step_offset


def _heading_offset(yaw: float, side: str, width: float) -> np.ndarray:
    s = SIDE_SIGN[side] * 0.5 * width
    return np.array([-math.sin(yaw) * s, math.cos(yaw) * s, 0.0])


def _midline_advance(gait: GaitSection, stance_yaw: float, side: str) -> np.ndarray:
    """How far the midline moves (m, world) when foot ``side`` steps off a stance at ``stance_yaw``.

    The midline of a foot at yaw ψ is its sole centre minus ``_heading_offset(ψ, side, w)``; the
    step lands at (Δx, ±w) in the stance frame with yaw ψ + turn (module docstring), so the
    midline moves by R(ψ)(Δx + s w/2 sin Δψ, s w/2 (1 − cos Δψ)) with s = ±1 the step's side.
    Straight walking: exactly (L cos ψ, L sin ψ, Δz).
    """
    turn, w = gait.turn, gait.step_width
    dx, _ = generated_step_offset(gait.step_length, w, turn)
    s = SIDE_SIGN[side] * 0.5 * w
    a = dx + s * math.sin(turn)
    b = s * (1.0 - math.cos(turn))
    c, n = math.cos(stance_yaw), math.sin(stance_yaw)
    return np.array([c * a - n * b, n * a + c * b, gait.step_height])


def initial_feet(gait: GaitSection) -> dict[str, Footstep]:
    """Standing feet at t = 0: sole centres at (0, ±step_width/2, 0)."""
    return {
        side: Footstep(side, _heading_offset(0.0, side, gait.step_width), 0.0)
        for side in ("left", "right")
    }


def generated_step(gait: GaitSection, k: int, *, closing: bool) -> Footstep:
    """Footstep k ≥ 1 of the generated plan: yaw k·turn, (Δx, ±w) in footstep k−1's frame.

    With ``closing`` the step lands beside the previous one (the plan's last step).
    """
    side = gait.first_swing if k % 2 == 1 else OTHER[gait.first_swing]
    m = np.zeros(3)
    yaw = 0.0
    last = k - 1 if closing else k
    for j in range(1, last + 1):
        side_j = gait.first_swing if j % 2 == 1 else OTHER[gait.first_swing]
        m = m + _midline_advance(gait, (j - 1) * gait.turn, side_j)
        yaw = j * gait.turn
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

    Each step is placed relative to its stance foot, (Δx, ±w) in its frame with yaw + turn (the
    module docstring), so an adjusted (really landed) foot shifts the walk only through the stance
    it leaves behind.
    """
    feet = dict(start_feet)
    side = next_side
    out = []
    for _ in range(count):
        stance = feet[OTHER[side]]
        yaw = stance.yaw + gait.turn
        mid = stance.position - _heading_offset(stance.yaw, stance.side, gait.step_width)
        mid = mid + _midline_advance(gait, stance.yaw, side)
        step = Footstep(side, mid + _heading_offset(yaw, side, gait.step_width), yaw)
        out.append(step)
        feet[side] = step
        side = OTHER[side]
    return tuple(out)


def on_terrain(steps: tuple[Footstep, ...], terrain: Terrain) -> tuple[Footstep, ...]:
    """The footsteps at the height of the ground under their sole centres (a flat floor: as they
    are)."""
    if terrain.flat:
        return steps
    heights = terrain.height_at(np.array([s.position[:2] for s in steps]))
    return tuple(
        s.moved(np.array([s.position[0], s.position[1], float(h)]))
        for s, h in zip(steps, heights, strict=True)
    )
