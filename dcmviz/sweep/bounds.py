"""What a push towards the stance foot can be at most: without crossing steps (the stance-edge
bound), and with a footstep across the stance foot (the crossover bound).

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
for Talos's torso, whose CoM is h = 0.379 m above the robot's (0.877 m high).  If the trunk took
that moment as centroidal angular momentum instead and gave it back only once ξ is caught (the
hip strategy), the lever would not count: ``moment_at_feet=False`` gives that bound, the point
mass's (Talos at mid single support: 41.8 N·s against 29.3 with the feet taking the moment).
On Talos, whose arms are locked, the QP that lets the trunk roll (force task weighted 100×
higher) keeps ξ but tips the trunk past the fall criterion, and giving the momentum back while
the CoP sits on the edge holds the CMP on ξ (measured: issue 22's notes).

A crossed footstep (the ``crossover`` strategy) moves that edge: the swinging foot lands across
the stance foot inside the robot's crossover region (:mod:`dcmviz.robots.crossover`), as far
out as the region allows, as early as the swing may (``timing.MIN_REMAINING_S`` from the push's
start, and no sooner than ``timing.MIN_SS_S`` after its lift-off); from then on the CoP can sit
on that sole's outer edge.  The crossover bound (:func:`crossover_bound`) is the largest impulse
after which ξ is still inside that edge when the push ends and the foot is down: the DCM a single
crossed footstep captures, the CoP on the stance edge until it lands.
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


def crossed_edge_impulse(
    stance_edge_m: float,
    crossed_edge_m: float,
    touchdown_s: float,
    mass_kg: float,
    b: float,
    duration_s: float,
    lever_m: float = 0.0,
) -> float:
    """Largest impulse (N·s) of a push held ``duration_s`` from ξ_0 = 0 (edges measured outwards
    from ξ_0) such that, with the CoP on the stance edge until ``touchdown_s`` and on the crossed
    foot's edge after it, ξ is inside the crossed edge once both the push is over and the foot is
    down.  ξ̇ = (ξ − p)/b + (F/m)(b + h/(g b)) (eq. 2 with the push and its lever) in closed form
    per piece; bisection on F (ξ at the end grows with F)."""
    gain = b * b + lever_m / GRAVITY

    def xi_end(force: float) -> float:
        shift = gain * force / mass_kg  # the push as a shift of the CoP, b² F/m (+ the lever's)
        xi, t = 0.0, 0.0
        for t_next in sorted({min(touchdown_s, duration_s), max(touchdown_s, duration_s)}):
            cop = stance_edge_m if t < touchdown_s else crossed_edge_m
            c = cop - (shift if t < duration_s else 0.0)
            xi = c + math.exp((t_next - t) / b) * (xi - c)
            t = t_next
        return xi

    lo, hi = 0.0, 1.0
    while xi_end(hi) <= crossed_edge_m and hi < 1e7:
        hi *= 2.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if xi_end(mid) <= crossed_edge_m else (lo, mid)
    return lo * duration_s


def stance_edge_bound(
    config: Config,
    step: int,
    phase: float,
    duration_s: float,
    angle_rad: float,
    *,
    backend: str = "lip",
    body: str = "torso",
    moment_at_feet: bool = True,
) -> float | None:
    """The bound (N·s) for a push at ``angle_rad`` (0 = +x, counter-clockwise) at ``phase`` of
    step ``step``'s single support (1-based) of the nominal plan, from the plan's ξ_ref there;
    None when the push has no component towards the stance foot.  The point mass (``backend``
    "lip") is pushed at its CoM; a humanoid at ``body``, whose lever above the CoM counts unless
    ``moment_at_feet`` is False (the trunk takes the push's moment as angular momentum)."""
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
    lever = 0.0 if backend == "lip" or not moment_at_feet else robot.push_lever_m(body)
    return edge_impulse(distance, spec.mass_kg, config.dcm.b, duration_s, lever) / cos


def crossover_bound(
    config: Config,
    step: int,
    phase: float,
    duration_s: float,
    angle_rad: float,
    *,
    backend: str = "lip",
    body: str = "torso",
) -> float | None:
    """The crossover bound (N·s, module docstring) for a push at ``angle_rad`` at ``phase`` of
    step ``step``'s single support; None without a part towards the stance foot or without a
    crossover region (a robot whose legs cannot cross within its reach)."""
    from dcmviz.gait import timing

    plan = plan_from_config(config)
    start, t_lift, _ = push_window(config, step, phase)
    stance = plan.stance_for(step - 1)
    robot = load_robot(config.robot.model)
    spec, region = robot.spec, robot.crossover
    if not region.polygons:
        return None
    outward = SIDE_SIGN[stance.side] * np.array([-math.sin(stance.yaw), math.cos(stance.yaw)])
    cos = float(outward @ np.array([math.cos(angle_rad), math.sin(angle_rad)]))
    if cos <= 1e-9:
        return None
    xi0 = float(outward @ plan.preview.dcm(start - plan.t0)[:2])
    centre = float(outward @ stance.position[:2])
    half = 0.5 * spec.foot_width_m
    # the lateral axis of the region points to the swinging foot's side: across is −lateral
    farthest = max(-float(p[:, 1].min()) for p in region.polygons)
    touchdown = max(timing.MIN_REMAINING_S, t_lift + timing.MIN_SS_S - start)
    lever = 0.0 if backend == "lip" else robot.push_lever_m(body)
    return crossed_edge_impulse(
        centre + half - xi0, centre + farthest + half - xi0, touchdown, spec.mass_kg,
        config.dcm.b, duration_s, lever,
    ) / cos  # fmt: skip
