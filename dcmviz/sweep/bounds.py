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
crossed footstep captures, the CoP on the stance edge until it lands.  A humanoid's legs add a
limit the point mass has not: the pelvis hangs over the CoM, and a crossed sole lands at most
``Robot.crossover_reach`` past the CoM (on Talos 0.13 m in front of the stance foot, 0.17 m
behind it, against the 0.225 m past the stance foot's centre that the region reaches with the
CoM over the middle of the soles).  So for a humanoid the crossed edge is the nearer of the region's
and the CoM's at the landing plus that reach (:func:`crossed_reach_impulse`, the CoM from ċ =
(ξ − c)/b, the reference CoM at the push's start), the landing at any instant from the earliest
on (a later one lets the CoM get further out).

Both assume the stance foot lifts only once the other foot holds ξ (a walker's rule: its single
supports of at least ``timing.MIN_SS_S`` need it).  What no footsteps can do at all, for a push of
any length at any time in the gait (``*_at``: from a global start time, double supports
included), is :func:`footstep_bound_at` (:func:`footstep_impulse`): a lateral model that favours
the walk wherever it simplifies (the CoP on the farthest edge any sole has reached, the feet
stepping in turn as early and as far out as the robot reaches, the pushed foot lifting the
instant the other is down whatever ξ does); beyond it no walk catches ξ.  It lies above the
stance-edge bound (tests/test_sweep_bounds.py checks it against an integrated LIP and against
walks that step later or shorter).

That model lets the CoP stay on the pushed sole's edge while that foot swings, which no walk
can.  The swing bound (:func:`swing_bound_at`, :func:`swing_impulse`) keeps the CoP on the soles
that stand: while the pushed foot swings out, the CoP is on the other sole's edge, so when to
lift it matters (a lift too early loses ξ on the way, a lift too late lets ξ run first), and it
swings as a walker's foot does, no faster than ``max_swing_speed_m_s`` on average and no shorter
than ``timing.MIN_SS_S``.  It searches the lift-offs; beyond it no walk with such swings catches
ξ (the G1 at 3.625 s, the paper's push pair with the torso's moment at the feet: 1.43× against
the footstep bound's 2.33×; tests/test_sweep_bounds.py integrates its walks).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dcmviz import GRAVITY
from dcmviz.config import Config
from dcmviz.gait import plan_from_config, timing
from dcmviz.gait.plan import GaitPlan
from dcmviz.robots import load_robot
from dcmviz.robots.feet import OTHER, SIDE_SIGN, Footstep
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
    per piece; bisection on F (ξ at the end grows with F): :func:`crossed_reach_impulse` with no
    reach from the CoM."""
    return crossed_reach_impulse(
        stance_edge_m, crossed_edge_m, math.inf, 0.0, touchdown_s, mass_kg, b, duration_s, lever_m
    )


def _largest_force(holds, bisections: int = 80) -> float:
    """The largest F ≥ 0 (N) with ``holds(F)``, for a ``holds`` true up to some force and false
    beyond it: doubled from 1 N until it fails (or 10⁷ N), then ``bisections`` bisections."""
    lo, hi = 0.0, 1.0
    while holds(hi) and hi < 1e7:
        hi *= 2.0
    for _ in range(bisections):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if holds(mid) else (lo, mid)
    return lo


def crossed_reach_impulse(
    stance_edge_m: float,
    crossed_edge_m: float,
    reach_edge_m: float,
    com_m: float,
    landing_s: float,
    mass_kg: float,
    b: float,
    duration_s: float,
    lever_m: float = 0.0,
) -> float:
    """:func:`crossed_edge_impulse` with the crossed sole's edge also at most ``reach_edge_m``
    past the CoM at the landing (the legs' reach past the CoM plus half a sole): ξ_0 = 0, the CoM
    ``com_m`` from it at the push's start, ċ = (ξ − c)/b.  Per piece of constant CMP p (the CoP
    moved by the push and its lever): ξ = p + (ξ_0 − p) e^{t/b}, c = p + (c_0 − p) e^{−t/b} +
    (ξ_0 − p) sinh(t/b); bisection on F."""
    gain = b * b + lever_m / GRAVITY

    def margin(force: float) -> float:
        """The crossed edge minus ξ once the push is over and the foot is down."""
        shift = gain * force / mass_kg
        xi, com, t, edge = 0.0, com_m, 0.0, stance_edge_m
        for t_next in sorted({min(landing_s, duration_s), max(landing_s, duration_s)}):
            p = edge - (shift if t < duration_s else 0.0)
            tau = t_next - t
            grow = math.exp(tau / b)
            com = p + (com - p) / grow + (xi - p) * 0.5 * (grow - 1.0 / grow)
            xi = p + grow * (xi - p)
            t = t_next
            if t >= landing_s and edge == stance_edge_m:  # the crossed foot lands now
                edge = min(crossed_edge_m, com + reach_edge_m)
        return edge - xi

    return _largest_force(lambda force: margin(force) >= 0.0) * duration_s


LANDING_SEARCH_S = 0.5  # a crossed landing this long after the earliest at most (the bound's max)
LANDING_STEP_S = 0.01


def reference_com(plan: GaitPlan, t: float, dt: float = 0.002) -> np.ndarray:
    """The plan's reference CoM (x, y) at global time ``t``: ċ = (ξ_ref − c)/b from the plan's
    start, where the robot stands (c = ξ_ref), exact per step for ξ_ref at its midpoint."""
    preview = plan.preview
    local = min(max(t - plan.t0, 0.0), preview.duration)
    n = max(1, math.ceil(local / dt))
    h = local / n
    xi = preview.dcm(np.minimum((np.arange(n) + 0.5) * h, preview.duration - 1e-12))[:, :2]
    c = preview.dcm(0.0)[:2].copy()
    decay = math.exp(-h / preview.b)
    for k in range(n):
        c = xi[k] + (c - xi[k]) * decay
    return c


def footstep_impulse(
    edge_distance_m: float,
    reach_m: float,
    step_out_m: float,
    landing_s: float,
    swing_s: float,
    mass_kg: float,
    b: float,
    duration_s: float,
    lever_m: float = 0.0,
) -> float:
    """Largest impulse (N·s) of a constant push held ``duration_s`` that footsteps may still
    save (beyond it none do), on a lateral model that favours the walk wherever it simplifies:
    the CoP on the outermost edge any sole has reached so far (even while that foot swings), the
    pushed sole's ``edge_distance_m`` beyond ξ_0 at first; the other foot down ``landing_s`` after
    the push's start with its sole's edge ``reach_m`` past the pushed one's (< 0: inside it),
    then the feet in turn, each lifting the instant the other lands and down ``swing_s`` later,
    the pushed side's ``step_out_m`` (the widest step) out from the other, the other's
    ``reach_m`` past it.  Each landing as early and as far out as it can be raises that edge the
    most at every instant, and ξ is the lower the farther out the CoP, so if this walk loses ξ
    every walk does.  After the push, at each landing, ξ − edge = Δ grows to E Δ − a over the
    next swing (E = e^{swing/b}, a the next landing's gain): ξ is lost iff Δ exceeds the fixed
    point (E a₁ + a₂)/(E² − 1) of the next two (the chain repeats every two steps).  During the
    push the CoP is moved by s = (b² + h/g) F/m (the lever's moment at the feet); bisection on F
    (ξ grows with F)."""
    gain = b * b + lever_m / GRAVITY
    grow = math.exp(swing_s / b)

    def landings():  # (time, the edge it reaches) in turn: the other foot, then the pushed one
        t, pushed, other, k = landing_s, edge_distance_m, None, 0
        while True:
            if k % 2 == 0:
                other = pushed + reach_m
                yield t, other
            else:
                pushed = other + step_out_m
                yield t, pushed
            t, k = t + swing_s, k + 1

    def lost(force: float) -> bool:
        shift = gain * force / mass_kg
        xi, t, cop = 0.0, 0.0, edge_distance_m
        chain = landings()
        for t_land, edge in chain:
            for t_next in sorted({min(duration_s, t_land), t_land}):  # the push's end on the way
                c = cop - (shift if t < duration_s else 0.0)
                xi = c + math.exp((t_next - t) / b) * (xi - c)
                t = t_next
            cop = max(cop, edge)
            if t_land >= duration_s:  # the push is over: capturable by the chain ahead?
                (_, e1), (_, e2) = next(chain), next(chain)
                a1 = max(e1 - cop, 0.0)
                a2 = max(e2 - max(cop, e1), 0.0)
                return xi - cop > (grow * a1 + a2) / (grow * grow - 1.0)
        return True  # not reached: the chain is endless

    return _largest_force(lambda force: not lost(force)) * duration_s


@dataclass(frozen=True)
class PushedFoot:
    """The foot a push points towards, standing when the push starts, and what a bound reads off
    the nominal plan there (all along ``outward``, the horizontal unit pointing away from the
    other foot)."""

    foot: Footstep
    outward: np.ndarray  # (2,) the horizontal unit away from the other foot
    cos: float  # of the push's direction with ``outward`` (> 0)
    xi0: float  # ξ_ref at the push's start (m, along outward)
    centre: float  # the pushed sole's centre (m, along outward); its outer edge is half a width on
    # the other foot down at the earliest, s after the push's start: no single support shorter
    # than timing.MIN_SS_S after it lifted (swinging) or may lift (double support: the push's
    # start), and no sooner than timing.MIN_REMAINING_S
    landing_s: float


def standing_foot(plan: GaitPlan, side: str, t: float) -> Footstep | None:
    """Where the ``side`` foot stands at global time ``t`` in the nominal plan (the last of its
    footsteps down by then, else where it started); None while it swings."""
    for k in range(len(plan.steps) - 1, -1, -1):
        if plan.steps[k].side != side:
            continue
        t_lift, t_touch = plan.swing_window(k)
        if t_touch <= t:
            return plan.steps[k]
        if t_lift <= t:
            return None
    return plan.start_feet[side]


def pushed_foot(
    plan: GaitPlan, foot_width_m: float, start_s: float, angle_rad: float
) -> PushedFoot | None:
    """What a bound needs of a push at ``angle_rad`` starting at ``start_s`` (module docstring),
    or None where no bound applies: the push has no part across the feet, the foot it points to
    swings (its footstep can go out under ξ), or both feet stand and ξ lies over the other sole
    (the pushed foot may lift at once and step out).  Otherwise the other foot has to land
    before the pushed one may lift (:func:`footstep_impulse`'s walk)."""
    direction = np.array([math.cos(angle_rad), math.sin(angle_rad)])
    for side in SIDE_SIGN:
        foot = standing_foot(plan, side, start_s)
        if foot is None:  # this foot swings: a push towards it is its footstep's to catch
            continue
        outward = SIDE_SIGN[side] * np.array([-math.sin(foot.yaw), math.cos(foot.yaw)])
        cos = float(outward @ direction)
        if cos <= 1e-9:
            continue
        xi0 = float(outward @ plan.preview.dcm(start_s - plan.t0)[:2])
        centre = float(outward @ foot.position[:2])
        other = standing_foot(plan, OTHER[side], start_s)
        if other is None:  # the other foot swings: it lifted at its footstep's lift-off
            k = plan.next_modifiable_step(start_s)
            lift = plan.swing_window(k)[0] if k is not None else start_s
        else:
            if xi0 <= float(outward @ other.position[:2]) + 0.5 * foot_width_m:
                return None  # ξ over the other sole: the pushed foot may lift and step out
            lift = start_s  # at the earliest
        landing = max(timing.MIN_REMAINING_S, lift + timing.MIN_SS_S - start_s)
        return PushedFoot(foot, outward, cos, xi0, centre, landing)
    return None


def _pushed(config: Config, start_s: float, angle_rad: float, backend: str, body: str,
            moment_at_feet: bool):  # fmt: skip
    """(robot, nominal plan, pushed foot, lever) of a push, or None where no bound applies: the
    common part of the ``*_bound_at`` functions (the lever 0 for the point mass, or with the
    trunk taking the push's moment)."""
    robot = load_robot(config.robot.model)
    plan = plan_from_config(config)
    pushed = pushed_foot(plan, robot.spec.foot_width_m, start_s, angle_rad)
    if pushed is None:
        return None
    lever = 0.0 if backend == "lip" or not moment_at_feet else robot.push_lever_m(body)
    return robot, plan, pushed, lever


def stance_edge_bound_at(
    config: Config,
    start_s: float,
    duration_s: float,
    angle_rad: float,
    *,
    backend: str = "lip",
    body: str = "torso",
    moment_at_feet: bool = True,
) -> float | None:
    """The stance-edge bound (N·s) of a push at ``angle_rad`` (0 = +x, counter-clockwise) held
    ``duration_s`` from ``start_s`` (global s, any instant of the nominal plan): the CoP on the
    pushed foot's outer edge from the push's start, ξ must still be inside that edge when the
    push ends (:func:`edge_impulse`, from the plan's ξ_ref there; :func:`pushed_foot` says when
    it applies, else None).  The point mass (``backend`` "lip") is pushed at its CoM; a humanoid
    at ``body``, whose lever above the CoM counts unless ``moment_at_feet`` is False (the trunk
    takes the push's moment as angular momentum)."""
    found = _pushed(config, start_s, angle_rad, backend, body, moment_at_feet)
    if found is None:
        return None
    robot, _, pushed, lever = found
    spec = robot.spec
    distance = pushed.centre + 0.5 * spec.foot_width_m - pushed.xi0
    return edge_impulse(distance, spec.mass_kg, config.dcm.b, duration_s, lever) / pushed.cos


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
    """:func:`stance_edge_bound_at` for a push at ``phase`` of step ``step``'s single support
    (1-based) of the nominal plan: None when the push has no component towards the stance
    foot."""
    start, _, _ = push_window(config, step, phase)
    return stance_edge_bound_at(
        config, start, duration_s, angle_rad, backend=backend, body=body,
        moment_at_feet=moment_at_feet,
    )  # fmt: skip


def crossover_bound_at(
    config: Config,
    start_s: float,
    duration_s: float,
    angle_rad: float,
    *,
    backend: str = "lip",
    body: str = "torso",
    moment_at_feet: bool = True,
) -> float | None:
    """The crossover bound (N·s, module docstring) of a push at ``angle_rad`` held
    ``duration_s`` from ``start_s``: the other foot lands across the pushed one as far out as the
    robot's crossover region allows, as early as the swing may (``timing.MIN_REMAINING_S`` from
    the push's start and ``timing.MIN_SS_S`` after it lifted, or may lift at the earliest); None
    where the stance-edge bound does not apply or without a crossover region."""
    found = _pushed(config, start_s, angle_rad, backend, body, moment_at_feet)
    if found is None or not found[0].crossover.polygons:
        return None
    robot, plan, pushed, lever = found
    spec = robot.spec
    farthest = reach_across(robot)
    centre, half, xi0 = pushed.centre, 0.5 * spec.foot_width_m, pushed.xi0
    b = config.dcm.b
    if backend == "lip":  # no legs: the region alone, landing as early as it may
        return crossed_edge_impulse(
            centre + half - xi0, centre + farthest + half - xi0, pushed.landing_s,
            spec.mass_kg, b, duration_s, lever,
        ) / pushed.cos  # fmt: skip
    com = float(pushed.outward @ reference_com(plan, start_s)) - xi0
    reach = robot.crossover_reach + half
    landings = pushed.landing_s + np.arange(0.0, LANDING_SEARCH_S + 1e-9, LANDING_STEP_S)
    edges = (centre + half - xi0, centre + farthest + half - xi0)
    moved = (spec.mass_kg, b, duration_s, lever)
    best = max(crossed_reach_impulse(*edges, reach, com, float(t), *moved) for t in landings)
    return best / pushed.cos


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
    """:func:`crossover_bound_at` for a push at ``phase`` of step ``step``'s single support;
    None without a part towards the stance foot or without a crossover region (a robot whose
    legs cannot cross within its reach)."""
    start, _, _ = push_window(config, step, phase)
    return crossover_bound_at(config, start, duration_s, angle_rad, backend=backend, body=body)


def reach_across(robot) -> float:
    """How far (m) the other foot's sole can reach past the pushed one's, laterally: the
    crossover region's farthest crossing (0 for a region that only reaches the stance foot's
    line, as the G1's), else −min_step_width (the feet keep that far apart)."""
    region = robot.crossover
    if region.polygons:  # its lateral axis points to the swinging foot's side: across is −lateral
        return max(-float(p[:, 1].min()) for p in region.polygons)
    return -robot.spec.min_step_width_m


def footstep_bound_at(
    config: Config,
    start_s: float,
    duration_s: float,
    angle_rad: float,
    *,
    backend: str = "lip",
    body: str = "torso",
    moment_at_feet: bool = True,
    crossing: bool = True,
) -> float | None:
    """The bound (N·s) beyond which no footsteps save the walk from a push at ``angle_rad`` held
    ``duration_s`` from ``start_s``, however long (:func:`footstep_impulse`): the CoP on the
    pushed sole's outer edge, the other foot down as early as a swing may (no single support
    shorter than ``timing.MIN_SS_S``, 0.35 s, the shortest any strategy plans: that long after it
    lifted, or after the push's start in double support, at the earliest; and
    ``timing.MIN_REMAINING_S`` from the push's start) as far across as the robot reaches
    (:func:`reach_across`; with ``crossing`` False the feet keep the robot's minimum step width
    apart, as every strategy but ``crossover`` does), then each foot in turn, the pushed side's
    as wide as the robot steps (``max_step_width_m``).  None where :func:`pushed_foot` says no
    bound applies.  The point mass with its CMP inside the soles: angular momentum beyond the
    push's own moment (``moment_at_feet`` False: the trunk takes that) is not counted."""
    found = _pushed(config, start_s, angle_rad, backend, body, moment_at_feet)
    if found is None:
        return None
    robot, _, pushed, lever = found
    spec = robot.spec
    distance = pushed.centre + 0.5 * spec.foot_width_m - pushed.xi0
    reach = reach_across(robot) if crossing else -spec.min_step_width_m
    return footstep_impulse(
        distance, reach, spec.max_step_width_m, pushed.landing_s, timing.MIN_SS_S, spec.mass_kg,
        config.dcm.b, duration_s, lever,
    ) / pushed.cos  # fmt: skip


SWING_WAIT_STEP_S = 0.01  # the lift-offs searched: this far apart
SWING_WAIT_MAX_S = 1.2  # ... up to this long after the foot may lift
SWING_LIFTS = 3  # lift-offs of the pushed side's foot searched in turn (more change nothing)
SWING_WIDTHS = 4  # steps searched between the widest and the widest a shortest swing reaches


@dataclass(frozen=True)
class SwingWalk:
    """A walk of :func:`swing_impulse`'s model: the pushed side's lift-offs and every landing,
    (time s, the landed sole's outer edge m, along the push's outward axis, from ξ_0)."""

    lifts: tuple[float, ...]
    landings: tuple[tuple[float, float], ...]
    # the search ended (SWING_LIFTS lift-offs) with ξ not yet lost to footstep_impulse's walk:
    # counted as caught, so that the bound stays one (no walk beyond it) where the search is cut
    cut: bool = False


def swing_walk(
    edge_distance_m: float,
    reach_m: float,
    step_out_m: float,
    landing_s: float,
    min_swing_s: float,
    swing_speed_m_s: float,
    shift_m: float,
    b: float,
    duration_s: float,
) -> SwingWalk | None:
    """A walk that catches ξ in :func:`swing_impulse`'s model under a push that moves the CoP by
    ``shift_m`` while it lasts (``duration_s``), or None if none of those searched does."""
    if step_out_m + reach_m <= 0.0:
        raise ValueError(f"step_out_m + reach_m = {step_out_m + reach_m}: must be > 0 (a step out)")

    def advance(xi: float, t0: float, t1: float, cop: float) -> float:
        for a, c in ((t0, min(max(duration_s, t0), t1)), (min(max(duration_s, t0), t1), t1)):
            if c > a:
                v = cop - (shift_m if a < duration_s else 0.0)
                xi = v + math.exp((c - a) / b) * (xi - v)
        return xi

    def swing(distance: float) -> float:
        return max(min_swing_s, abs(distance) / swing_speed_m_s)

    # beyond this far past the soles' edge ξ is lost even to footstep_impulse's walk, whose
    # CoP stays out and whose swings are the shortest: the fixed point of its chain of landings
    # (each raising the edge by a₁, a₂ in turn)
    grow = math.exp(min_swing_s / b)
    a1, a2 = step_out_m + reach_m, max(reach_m, 0.0)
    lost = (grow * a1 + a2) / (grow * grow - 1.0)

    fast = swing_speed_m_s * min_swing_s  # the farthest a swing of min_swing_s goes

    def outs(outer: float, inner: float) -> list[float]:
        # as far out as it steps (its edge step_out_m past the other's); where that swing is
        # slower than min_swing_s, nearer ones too: they land sooner
        far = inner + step_out_m
        near = max(outer + fast, inner + 1e-3)
        if near >= far:
            return [far]
        return [far - (far - near) * i / (SWING_WIDTHS - 1) for i in range(SWING_WIDTHS)]

    def backs(out: float, inner: float) -> list[float]:
        # as near the pushed side's sole as it may (``reach_m`` past it), or sooner where that
        # swing is slower than min_swing_s
        near = out + reach_m
        soon = inner + fast
        return [near] if soon >= near else [near, soon]

    def walk(xi, t, outer, inner, lifts, landings, depth):
        # both feet down, the pushed side's sole (edge ``outer``) and the other's (``inner``)
        cop = max(outer, inner)
        if t >= duration_s and xi <= cop:
            return SwingWalk(tuple(lifts), tuple(landings))
        if depth == 0:
            return SwingWalk(tuple(lifts), tuple(landings), cut=True) if xi - cop <= lost else None
        # waiting for a lift-off helps only while the push lasts (after it, a ξ outside the
        # edge only runs further)
        waits = min(int(round(SWING_WAIT_MAX_S / SWING_WAIT_STEP_S)),
                    max(0, math.ceil((duration_s - t) / SWING_WAIT_STEP_S)))  # fmt: skip
        for k in range(waits + 1):
            lift = t + k * SWING_WAIT_STEP_S
            x1 = advance(xi, t, lift, cop)
            if lift >= duration_s and x1 <= cop:
                return SwingWalk(tuple(lifts), tuple(landings))
            if x1 - cop > lost:  # (a push still on only makes it run faster)
                return None  # lost now, and later lift-offs find ξ further out
            for out in outs(outer, inner):  # the pushed side's foot steps out
                t_out = lift + swing(out - outer)
                x2 = advance(x1, lift, t_out, inner)  # on the other sole meanwhile
                if t_out >= duration_s and x2 <= out:
                    return SwingWalk((*lifts, lift), (*landings, (t_out, out)))
                for back in backs(out, inner):  # the other lifts as this one lands, steps in
                    t_in = t_out + swing(back - inner)
                    x3 = advance(x2, t_out, t_in, out)  # on the pushed side's sole meanwhile
                    found = walk(x3, t_in, out, back, (*lifts, lift), (*landings, (t_out, out),
                                 (t_in, back)), depth - 1)  # fmt: skip
                    if found is not None:
                        return found
        return None

    xi = advance(0.0, 0.0, landing_s, edge_distance_m)
    other = edge_distance_m + reach_m  # the other foot down as early as it may, as near
    return walk(xi, landing_s, edge_distance_m, other, [], [(landing_s, other)], SWING_LIFTS)


def swing_impulse(
    edge_distance_m: float,
    reach_m: float,
    step_out_m: float,
    landing_s: float,
    min_swing_s: float,
    swing_speed_m_s: float,
    mass_kg: float,
    b: float,
    duration_s: float,
    lever_m: float = 0.0,
) -> float:
    """Largest impulse (N·s) of a constant push held ``duration_s`` that a walk with a walker's
    swings may still save, on a lateral LIP with the CoP on the outermost edge of the soles that
    stand: the pushed sole's ``edge_distance_m`` beyond ξ_0 at first, the other foot down
    ``landing_s`` after the push's start with its edge ``reach_m`` past the pushed one's (< 0:
    inside it); then the pushed side's foot lifts when the search says (every
    ``SWING_WAIT_STEP_S`` up to ``SWING_WAIT_MAX_S`` after it may), the CoP on the other sole
    while it swings, and lands ``step_out_m`` (the widest step) out from the other, which lifts
    as it lands and comes back to ``reach_m`` past it; a swing lasts its distance over
    ``swing_speed_m_s`` and at least ``min_swing_s``.  ξ is caught when, the push over, it is
    inside the soles' outer edge.  With swings of ``min_swing_s``, steps as wide and landings as
    early as they may be keep the soles' edge the farthest out at every instant; where the
    widest step swings longer, ``SWING_WIDTHS`` nearer ones (down to the widest a shortest swing
    reaches) and a sooner step back are searched too.  A foot whose edge is inside the other's
    loses nothing by lifting at once, so only the pushed side's lift-offs are searched
    (``SWING_LIFTS`` of them; where the search ends with ξ still within what
    :func:`footstep_impulse`'s walk catches, it counts as caught, so the number stays a bound:
    3 lift-offs against 5 raise it by at most 0.05 %).  The push's lever counts as in :func:`edge_impulse`; bisection on
    F (ξ grows with F)."""
    gain = b * b + lever_m / GRAVITY

    def holds(force: float) -> bool:
        return swing_walk(
            edge_distance_m, reach_m, step_out_m, landing_s, min_swing_s, swing_speed_m_s,
            gain * force / mass_kg, b, duration_s,
        ) is not None  # fmt: skip

    # 40 bisections: to 1e-12 of the doubling's bracket, far below the search's grid (each one
    # is a whole search)
    return _largest_force(holds, bisections=40) * duration_s


def swing_bound_at(
    config: Config,
    start_s: float,
    duration_s: float,
    angle_rad: float,
    *,
    backend: str = "lip",
    body: str = "torso",
    moment_at_feet: bool = True,
    crossing: bool = True,
) -> float | None:
    """The swing bound (N·s, module docstring) of a push at ``angle_rad`` held ``duration_s``
    from ``start_s``: :func:`footstep_bound_at`'s walk with the CoP on the soles that stand and
    the robot's swings (``max_swing_speed_m_s``, ``timing.MIN_SS_S``), the lift-offs searched
    (:func:`swing_impulse`).  None where :func:`pushed_foot` says no bound applies."""
    found = _pushed(config, start_s, angle_rad, backend, body, moment_at_feet)
    if found is None:
        return None
    robot, _, pushed, lever = found
    spec = robot.spec
    distance = pushed.centre + 0.5 * spec.foot_width_m - pushed.xi0
    reach = reach_across(robot) if crossing else -spec.min_step_width_m
    return swing_impulse(
        distance, reach, spec.max_step_width_m, pushed.landing_s, timing.MIN_SS_S,
        spec.max_swing_speed_m_s, spec.mass_kg, config.dcm.b, duration_s, lever,
    ) / pushed.cos  # fmt: skip


def swing_bound(
    config: Config,
    step: int,
    phase: float,
    duration_s: float,
    angle_rad: float,
    *,
    backend: str = "lip",
    body: str = "torso",
    moment_at_feet: bool = True,
    crossing: bool = False,
) -> float | None:
    """:func:`swing_bound_at` for a push at ``phase`` of step ``step``'s single support, without
    crossing steps unless ``crossing``: what a strategy that keeps the feet apart can reach at
    most by stepping the stance foot out once the other is down (above the stance-edge bound,
    which waits for ξ back over the stance sole first)."""
    start, _, _ = push_window(config, step, phase)
    return swing_bound_at(
        config, start, duration_s, angle_rad, backend=backend, body=body,
        moment_at_feet=moment_at_feet, crossing=crossing,
    )  # fmt: skip
