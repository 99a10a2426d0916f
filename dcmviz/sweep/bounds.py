"""What no footstep strategy without crossing steps can exceed: a push towards the stance foot.

The swinging foot may not cross the stance leg (``min_step_width``), so until the stance foot
itself lifts off, the CoP (VRP) can lie no farther out than the stance sole's outer edge, and the
stance foot may lift off only once the other foot can hold ξ: with single supports of at least
``timing.MIN_SS_S`` that needs ξ back inside the stance sole (``timing.capture_shortfall``).
During a push of force F (N) held T seconds the DCM obeys ξ̇ = (ξ − v)/b + b F/m (eq. 2 with an
external force), so with the CoP at the edge e from the push's start,

    ξ(T) − e = e^{T/b} (ξ_0 − e) + b² F/m (e^{T/b} − 1),

and ξ(T) ≤ e needs the lateral impulse J = F T ≤ (e − ξ_0) m T / (b² (1 − e^{−T/b})).  A push at
angle θ to the lateral axis has a lateral part J cos θ: its bound is that divided by cos θ (the
forward part taken by footsteps for free, so a loose upper bound off the lateral axis).

A humanoid is pushed at a body (the torso by default), ``h`` above its CoM: the push also brings
a moment h F about the CoM.  The whole-body QP counters it with the feet (its external-moment
observer), which moves the CMP (the VRP the CoM actually feels) h F/(m g) inwards of the CoP on
the edge, so ξ̇ = (ξ − e)/b + (F/m)(b + h/(g b)) and b² becomes b² + h/g in the bound: 30 % less
for Talos's torso, whose CoM is h = 0.379 m above the robot's (0.877 m high).  Letting the trunk
roll instead (and righting it once the other foot is down) could in principle recover the rest;
on Talos, whose arms are locked, the QP that does so (force task weighted 100× higher) keeps ξ
but tips the trunk past the fall criterion.
"""

from __future__ import annotations

import math

import numpy as np

from dcmviz import GRAVITY
from dcmviz.config import Config
from dcmviz.gait import plan_from_config
from dcmviz.robots import load_robot
from dcmviz.robots.feet import SIDE_SIGN
from dcmviz.sweep.search import push_window


def edge_impulse(
    edge_distance_m: float, mass_kg: float, b: float, duration_s: float, lever_m: float = 0.0
) -> float:
    """Largest impulse (N·s) of a constant push held ``duration_s`` after which ξ is still inside
    a CoP edge ``edge_distance_m`` beyond ξ_0 (the CoP on that edge from the push's start), the
    push ``lever_m`` above the CoM and its moment taken by the feet (the CMP moved inwards)."""
    gain = b * b + lever_m / GRAVITY
    return edge_distance_m * mass_kg * duration_s / (gain * (1.0 - math.exp(-duration_s / b)))


def stance_edge_bound(
    config: Config,
    step: int,
    phase: float,
    duration_s: float,
    angle_rad: float,
    *,
    backend: str = "lip",
    body: str = "torso",
) -> float | None:
    """The bound (N·s) for a push at ``angle_rad`` (0 = +x, counter-clockwise) at ``phase`` of
    step ``step``'s single support (1-based) of the nominal plan, from the plan's ξ_ref there;
    None when the push has no component towards the stance foot.  The point mass (``backend``
    "lip") is pushed at its CoM; a humanoid at ``body``, whose lever above the CoM counts."""
    plan = plan_from_config(config)
    start, _, _ = push_window(config, step, phase)
    stance = plan.stance_for(step - 1)
    robot = load_robot(config.robot.model)
    spec = robot.spec
    outward = SIDE_SIGN[stance.side] * np.array([-math.sin(stance.yaw), math.cos(stance.yaw)])
    cos = float(outward @ np.array([math.cos(angle_rad), math.sin(angle_rad)]))
    if cos <= 1e-9:
        return None
    xi0 = plan.preview.dcm(start - plan.t0)[:2]
    edge = float(outward @ stance.position[:2]) + 0.5 * spec.foot_width_m
    distance = edge - float(outward @ xi0)
    lever = 0.0 if backend == "lip" else robot.push_lever_m(body)
    return edge_impulse(distance, spec.mass_kg, config.dcm.b, duration_s, lever) / cos
