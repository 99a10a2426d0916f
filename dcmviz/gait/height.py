"""How high the CoM can walk when the feet are apart: the legs' reach lowers the VRP.

Standing at its highest walking CoM height H_max a robot's hip is D = ``spec.leg_length_m``
above its ankles (knees still bent enough to walk).  While both feet are on the ground with the
CoM between them, each leg reaches a horizontal distance s from the hip to its ankle; with the
legs stretched no further than D the CoM can be at most

    H(s) = H_max − D + sqrt(D² − s²) − |Δz|/2

above the middle of the feet, Δz being the height between the two treads (on stairs the leg on
the lower tread reaches down half the rise further).  A plan whose Δz_vrp = g b² is higher than that for a footstep lowers that
footstep's VRP waypoints to H(s) (the paper's VRP is 3-D, eq. 2): the DCM and the CoM follow it
down smoothly through the preview, and back up when the feet come together.  b, and with it the
DCM's time constant, does not change.  :func:`dcmviz.gait.feasibility.check_plan` says so.

s is half the horizontal distance between the stance foot and the footstep, less the hips'
lateral spacing (taken as the robot's nominal foot spacing): in double support the CoM is near
the middle of the feet.
"""

from __future__ import annotations

import math

import numpy as np

from dcmviz.robots.feet import Footstep
from dcmviz.robots.spec import RobotSpec

# the CoM at touchdown is not yet in the middle of the feet: the swinging leg reaches further
# than half the stride (measured on Talos and the G1: the legs stretch as far as at s = 0.6 L)
REACH_FRACTION = 0.7


def leg_span_m(spec: RobotSpec, stance: Footstep, step: Footstep) -> float:
    """s (m): horizontal hip → ankle distance a leg spans while ``step`` lands beside ``stance``."""
    d = step.position[:2] - stance.position[:2]
    c, s = math.cos(stance.yaw), math.sin(stance.yaw)
    dx, dy = c * d[0] + s * d[1], -s * d[0] + c * d[1]
    lateral = max(0.0, abs(dy) - spec.foot_spacing_m)
    return REACH_FRACTION * math.hypot(dx, lateral)


def walk_height_m(spec: RobotSpec, span: float) -> float:
    """H(s): the highest CoM above the feet (m) with legs spanning ``span`` (inf: no limit)."""
    D = spec.leg_length_m
    if D is None:
        return math.inf
    if span >= D:
        return spec.max_com_height_m - D
    return spec.max_com_height_m - D + math.sqrt(D * D - span * span)


def stride_height_m(spec: RobotSpec, stance: Footstep, step: Footstep) -> float:
    """The highest CoM (m) above the middle of ``stance`` and ``step`` the legs allow (inf: any)."""
    rise = abs(float(step.position[2] - stance.position[2]))
    return walk_height_m(spec, leg_span_m(spec, stance, step)) - 0.5 * rise


def step_heights(
    spec: RobotSpec | None, dz: float, start_feet: dict[str, Footstep], steps: tuple[Footstep, ...]
) -> np.ndarray:
    """Δz (m) of each footstep's VRP waypoints: min(g b², H(s)) for the stance → step stride."""
    out = np.full(len(steps), float(dz))
    if spec is None or spec.leg_length_m is None:
        return out
    feet = dict(start_feet)
    for k, step in enumerate(steps):
        stance = feet["left" if step.side == "right" else "right"]
        out[k] = min(dz, stride_height_m(spec, stance, step))
        feet[step.side] = step
    return out
