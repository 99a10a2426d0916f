"""The stance-edge bound of a push towards the stance foot, and the bound beyond which no
footsteps save the walk from a long push (dcmviz.sweep.bounds)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from helpers import rk4, robustness_bench

from dcmviz.config import Config, load_preset
from dcmviz.gait import plan_from_config
from dcmviz.session import Session
from dcmviz.sweep.bounds import (
    edge_impulse,
    footstep_bound_at,
    footstep_impulse,
    stance_edge_bound,
    swing_bound_at,
    swing_impulse,
    swing_walk,
)
from dcmviz.sweep.search import push_window

ROOT = Path(__file__).resolve().parents[1]


def test_edge_impulse_leaves_the_dcm_on_the_edge() -> None:
    """Integrated LIP (ẍ = (x − v)/b² + F/m, RK4, CoP v on the edge): after the bound's impulse
    the DCM x + b ẋ ends on the edge, 5 % more ends outside, 5 % less inside."""
    m, b, T, d = 90.0, 0.3, 0.2, 0.1

    def final_dcm(impulse: float) -> float:
        F, n = impulse / T, 4000
        h = T / n
        y = np.array([0.0, 0.0])  # x, ẋ with ξ_0 = 0; the edge at d
        f = lambda s: np.array([s[1], (s[0] - d) / b**2 + F / m])  # noqa: E731
        y = rk4(f, y, h, n)
        return y[0] + b * y[1]

    J = edge_impulse(d, m, b, T)
    assert abs(final_dcm(J) - d) < 1e-9
    assert final_dcm(1.05 * J) > d + 1e-3 and final_dcm(0.95 * J) < d - 1e-3


def test_no_strategy_survives_beyond_the_bound_towards_the_stance_foot() -> None:
    """Point mass, push at mid single support of step 4 towards the left stance foot: the step
    timing strategy survives 85 % of the bound and falls at 102 % of it (it cannot cross)."""
    config = Config().replace(sim={"backend": "lip"}, control={"observer": False})
    angle = math.pi / 2
    bound = stance_edge_bound(config, 4, 0.5, 0.2, angle)
    plan = plan_from_config(config)
    assert plan.stance_for(3).side == "left"
    assert stance_edge_bound(config, 4, 0.5, 0.2, -angle) is None  # towards the swinging foot
    start = push_window(config, 4, 0.5)[0]

    def survives(impulse: float) -> bool:
        s = Session(config.replace(control={"recovery": "multi_step_timing"}), backend="lip")
        s.push((0.0, impulse / 0.2, 0.0), 0.2, start=start)
        s.run(start + 2.7)
        return not s.fell

    assert survives(0.85 * bound)
    assert not survives(1.02 * bound)


def test_a_humanoid_pushed_at_its_torso_has_the_lever_in_its_bound() -> None:
    """Talos in MuJoCo, pushed at its torso towards the left stance foot at mid single support
    of step 4: the torso's CoM (MuJoCo, where the force acts) stands as high above the robot's CoM
    (Pinocchio) as the bound's lever says, and the step timing strategy survives 85 % of that
    bound and falls at 105 % of it (the LIP bound without the lever is 43 % higher)."""
    import mujoco
    import pinocchio as pin

    from dcmviz.robots import load_robot

    config = load_preset(ROOT / "presets" / "walk_forward.toml").replace(
        pushes=[], control={"recovery": "multi_step_timing", "observer": False}
    )
    robot = load_robot("talos")
    data = mujoco.MjData(robot.mujoco.model)
    data.qpos[:] = robot.mujoco.qpos_mj(robot.q_nominal)
    mujoco.mj_kinematics(robot.mujoco.model, data)
    torso = data.body(robot.spec.bodies["torso"]).xipos[2]
    com = pin.centerOfMass(robot.pin_model, robot.pin_model.createData(), robot.q_nominal)[2]
    assert abs(load_robot("talos").push_lever_m("torso") - (torso - com)) < 2e-3

    angle = math.pi / 2
    bound = stance_edge_bound(config, 4, 0.5, 0.2, angle, backend="mujoco", body="torso")
    lip = stance_edge_bound(config, 4, 0.5, 0.2, angle)
    assert bound < 0.75 * lip
    start = push_window(config, 4, 0.5)[0]

    def survives(impulse: float) -> bool:
        s = Session(config, backend="mujoco")  # (a MuJoCo session cannot be pickled)
        s.push((0.0, impulse / 0.2, 0.0), 0.2, body="torso", start=start)
        s.run(start + 1.8)
        return not s.fell

    assert survives(0.85 * bound)
    assert not survives(1.05 * bound)


CHAIN_CASES = [  # d, reach, step out, landing, swing, T: the paper's 1 s push and the sweep's
    (0.05, 0.0, 0.4, 0.35, 0.35, 1.0),  # the other foot lands in line (the G1)
    (0.08, -0.14, 0.4, 0.12, 0.35, 1.0),  # ... kept the minimum width apart
    (0.1, 0.2, 0.5, 0.3, 0.35, 1.0),  # ... across, far out (Talos)
    (0.1, -0.14, 0.5, 0.12, 0.35, 0.2),  # a short push towards the stance foot
]
M, B, LEVER = 33.0, 0.26, 0.28


def chain(d, reach, out, landing, swing, T, impulse, lift_delays=None, shorten=None, n=14):
    """ξ − (the CoP's edge) at each landing of the walk of footstep_impulse's model, integrated
    with RK4 (the LIP ẍ = (x − c)/b² + gain F/(m b²), c the edge), for ``n`` landings; a strategy
    may lift later (``lift_delays`` s per step) and land shorter (``shorten`` m per step)."""
    gain = B * B + LEVER / 9.81
    F = impulse / T
    y, t, cop = np.array([0.0, 0.0]), 0.0, d
    pushed, other = d, None
    t_land, out_gaps = landing, []
    for k in range(n):
        for a, z in ((t, min(T, t_land)), (max(t, T), t_land)):  # pushed, then not
            if z <= a:
                continue
            push = gain * F / M if a < T else 0.0
            f = lambda yy, c=cop, p=push: np.array([yy[1], (yy[0] - c + p) / B**2])  # noqa: E731
            steps = max(8, math.ceil((z - a) / 1e-3))
            y = rk4(f, y, (z - a) / steps, steps)
        t = t_land
        cut = 0.0 if shorten is None else shorten[k]
        if k % 2 == 0:
            other = pushed + reach - cut
            cop = max(cop, other)
        else:
            pushed = other + out - cut
            cop = max(cop, pushed)
        out_gaps.append((t, y[0] + B * y[1] - cop))
        t_land = t + swing + (0.0 if lift_delays is None else lift_delays[k])
    return out_gaps


@pytest.mark.parametrize("case", CHAIN_CASES)
def test_footstep_impulse_is_where_the_fastest_widest_steps_just_catch_the_dcm(case) -> None:
    """Integrated LIP: the steps of footstep_impulse's model (each as early and as far out as
    allowed) catch ξ (ξ back behind the CoP's edge at a landing after the push) at 1 % below the
    bound and lose it (ξ past the edge by more than a metre) at 1 % above."""
    d, reach, out, landing, swing, T = case
    J = footstep_impulse(d, reach, out, landing, swing, M, B, T, LEVER)
    below = chain(*case, 0.99 * J)
    above = chain(*case, 1.01 * J)
    assert any(gap <= 0.0 for t, gap in below if t >= T)
    assert all(gap > 0.0 for t, gap in above if t >= T) and above[-1][1] > 1.0


@pytest.mark.parametrize("case", CHAIN_CASES)
def test_no_slower_or_shorter_steps_catch_the_dcm_beyond_the_footstep_bound(case) -> None:
    """Monte Carlo over 25 walks that lift later (up to 0.2 s per step) or land shorter (up to
    5 cm) than the bound's walk: at 1 % beyond the bound none catches ξ in 14 steps."""
    d, reach, out, landing, swing, T = case
    J = footstep_impulse(d, reach, out, landing, swing, M, B, T, LEVER)
    rng = np.random.default_rng(7)
    for _ in range(25):
        delays = rng.uniform(0.0, 0.2, 14) * rng.integers(0, 2, 14)
        shorter = rng.uniform(0.0, 0.05, 14) * rng.integers(0, 2, 14)
        gaps = chain(*case, 1.01 * J, delays, shorter)
        assert all(gap > 0.0 for t, gap in gaps if t >= T)


def test_for_a_short_push_the_footstep_bound_lies_above_the_stance_edge_bound() -> None:
    """Talos's point mass, 0.2 s at mid single support towards the stance foot: the stance-edge
    bound (the CoP on the edge, ξ inside it when the push ends) is a walker's; stepping the
    stance foot out once the other is down, even with ξ outside it, reaches further, and crossed
    steps further still; towards the swinging foot neither applies."""
    config = Config().replace(sim={"backend": "lip"}, control={"observer": False})
    start = push_window(config, 4, 0.5)[0]
    edge = stance_edge_bound(config, 4, 0.5, 0.2, math.pi / 2)
    uncrossed = footstep_bound_at(config, start, 0.2, math.pi / 2, crossing=False)
    crossed = footstep_bound_at(config, start, 0.2, math.pi / 2)
    assert edge < uncrossed < crossed
    assert footstep_bound_at(config, start, 0.2, -math.pi / 2) is None  # the swinging foot's way


G1_START_S = 3.625  # the paper's push pair from here: the first towards the left stance foot


@pytest.mark.parametrize("recovery", ["next_step", "multi_step_timing", "crossover"])
def test_no_footsteps_save_the_g1s_point_mass_beyond_the_bound_of_the_papers_push(
    recovery: str,
) -> None:
    """bench/robustness.py's push pair on the point mass with the G1's numbers, from a double
    support before a left stance (the G1's legs reach no further across than the stance foot's
    line): at 1.05, 1.2 and 1.5 times the bound the bench prints (in the push's scale, pushed at
    the CoM) every strategy falls, the crossing one included; at 1× of the paper's push each
    survives."""
    rb = robustness_bench()
    base = rb.walking_config("g1", sim="lip", overrides=[f'control.recovery="{recovery}"'])
    mass = Session(base, backend="lip").mass
    bounds = rb.push_bounds(base, G1_START_S)
    assert bounds["second"]["com"] is None  # the second push points to the swinging foot
    bound = bounds["first"]["com"]

    def fell(scale: float) -> bool:
        session = Session(rb.push_config(base, mass, scale, G1_START_S), backend="lip")
        return session.run(G1_START_S + rb.PUSH_S + 2.0).fell

    assert not fell(1.0)
    assert all(fell(k * bound) for k in (1.05, 1.2, 1.5))


# the swing bound: d, reach, step out, landing, shortest swing, swing speed, T
SWING_CASES = [
    (0.045, -0.071, 0.40, 0.35, 0.35, 1.5, 1.0),  # the G1 at 3.625 s: the other foot kept apart
    (0.05, 0.0, 0.40, 0.35, 0.35, 1.5, 1.0),  # ... landing in line with the pushed one
    (0.1, 0.2, 0.5, 0.3, 0.35, 1.8, 1.0),  # across, far out (Talos)
    (0.08, -0.14, 0.5, 0.12, 0.35, 1.0, 0.2),  # a short push; wide steps slower than 0.35 s
    (0.06, -0.13, 0.42, 0.35, 0.35, 0.72, 1.0),  # Romeo: its widest steps take 0.40 s
]


def integrate_walk(case, impulse, walk) -> float:
    """stand_walk's integration through the lift-offs and landings of a SwingWalk."""
    d, reach, out, landing, min_swing, speed, T = case
    (t, inner), *rest = walk.landings
    outer, segments = d, [(0.0, t, d)]
    for k, lift in enumerate(walk.lifts):
        segments.append((t, lift, max(outer, inner)))
        t_out, new = rest[2 * k]
        segments.append((lift, t_out, inner))
        t, outer = t_out, new
        if 2 * k + 1 < len(rest):
            t_in, back = rest[2 * k + 1]
            segments.append((t_out, t_in, new))
            t, inner = t_in, back
    segments.append((t, max(t, T) + 1.0, max(outer, inner)))
    return lowest_gap(segments, impulse, T)


def stand_walk(case, impulse, lifts, n_lifts=3, shorten=None):
    """min over t ≥ T of ξ − (the outer edge of the soles that stand), integrated with RK4 (the
    LIP ẍ = (x − c)/b² + gain F/(m b²)) through a walk of swing_impulse's model: the pushed
    side's foot lifting at ``lifts`` (s, each after the previous landing), landing a step out
    from the other (``shorten`` m less per step), the other lifting then and stepping back;
    > 0: ξ never caught."""
    d, reach, out, landing, min_swing, speed, T = case

    def swing(dist):
        return max(min_swing, abs(dist) / speed)

    segments = [(0.0, landing, d)]  # (from, to, the CoP's edge)
    outer, inner, t = d, d + reach, landing
    for k in range(n_lifts):
        lift = max(lifts[k], t)
        segments.append((t, lift, max(outer, inner)))
        new = inner + out - (0.0 if shorten is None else shorten[k])
        t_out = lift + swing(new - outer)
        segments.append((lift, t_out, inner))
        back = new + reach
        t_in = t_out + swing(back - inner)
        segments.append((t_out, t_in, new))
        outer, inner, t = new, back, t_in
    segments.append((t, max(t, T) + 1.0, max(outer, inner)))
    return lowest_gap(segments, impulse, T)


def lowest_gap(segments, impulse, T) -> float:
    """min over t ≥ T of ξ − the CoP's edge, RK4 through ``segments`` (from, to, edge)."""
    gain, F = B * B + LEVER / 9.81, impulse / T
    y, worst = np.array([0.0, 0.0]), math.inf
    for a, z, cop in segments:
        for lo, hi in ((a, min(z, max(a, T))), (max(a, T), z)):  # pushed, then not
            if hi <= lo:
                continue
            push = gain * F / M if lo < T else 0.0
            f = lambda yy, c=cop, p=push: np.array([yy[1], (yy[0] - c + p) / B**2])  # noqa: E731
            steps = max(4, math.ceil((hi - lo) / 2e-3))
            for _ in range(steps):
                y = rk4(f, y, (hi - lo) / steps, 1)
                if lo >= T - 1e-12:
                    worst = min(worst, y[0] + B * y[1] - cop)
    return worst


@pytest.mark.parametrize("case", SWING_CASES)
def test_the_swing_bounds_walk_catches_the_dcm_just_below_it(case) -> None:
    """Integrated LIP: the lift-offs swing_walk finds at 1 % below swing_impulse's bound catch ξ
    (ξ back inside the standing soles' edge after the push), and at 1 % above it finds none."""
    d, reach, out, landing, min_swing, speed, T = case
    J = swing_impulse(d, reach, out, landing, min_swing, speed, M, B, T, LEVER)
    gain = B * B + LEVER / 9.81
    walk = swing_walk(d, reach, out, landing, min_swing, speed, gain * 0.99 * J / T / M, B, T)
    assert walk is not None and not walk.cut  # a whole walk, not one the search's depth ended
    # the walk's lift-offs and landings, then it stands (ξ inside the edge goes on inwards)
    assert integrate_walk(case, 0.99 * J, walk) <= 1e-6
    assert swing_walk(d, reach, out, landing, min_swing, speed, gain * 1.01 * J / T / M, B,
                      T) is None  # fmt: skip


@pytest.mark.parametrize("case", SWING_CASES)
def test_no_lift_offs_or_shorter_steps_catch_the_dcm_beyond_the_swing_bound(case) -> None:
    """Monte Carlo over 60 walks lifting the pushed side's foot at random (up to 1.2 s after it
    may) and stepping up to 5 cm shorter, integrated: at 1 % beyond the bound none catches ξ;
    at 10 % below it some do (the search's walk is not the only one)."""
    d, reach, out, landing, min_swing, speed, T = case
    J = swing_impulse(d, reach, out, landing, min_swing, speed, M, B, T, LEVER)
    rng = np.random.default_rng(11)
    caught_below = 0
    for _ in range(60):
        waits = np.cumsum(rng.uniform(0.0, 1.2, 3) * rng.integers(0, 2, 3))
        lifts = list(landing + waits)
        shorter = rng.uniform(0.0, 0.05, 3) * rng.integers(0, 2, 3)
        assert stand_walk(case, 1.01 * J, lifts, shorten=shorter) > 0.0
        caught_below += stand_walk(case, 0.9 * J, lifts) <= 0.0
    assert caught_below > 0


@pytest.mark.parametrize("case", SWING_CASES)
def test_the_swing_bound_lies_below_the_footstep_bound(case) -> None:
    """The CoP under the standing feet only: never above footstep_impulse's model, which lets it
    stay on a swinging foot's edge; equal where the other foot lands in line or across (lifting
    the pushed foot then loses nothing) and its swings are the shortest."""
    d, reach, out, landing, min_swing, speed, T = case
    swing = swing_impulse(d, reach, out, landing, min_swing, speed, M, B, T, LEVER)
    loose = footstep_impulse(d, reach, out, landing, min_swing, M, B, T, LEVER)
    assert swing <= loose * (1.0 + 1e-9)
    if reach < 0.0:
        assert swing < 0.9 * loose


def test_the_g1s_point_mass_falls_beyond_the_swing_bound_without_crossing() -> None:
    """bench/robustness.py's push pair from 3.625 s on the point mass with the G1's numbers and
    the torso's moment on its CoP (forces × the lever factor): the swing bound without crossing
    the legs is below 1.5× of the paper's push (the footstep bound 2.10×), and every strategy
    that keeps the feet apart falls at 1.05, 1.2 and 1.5 times it, while at 0.7 times it they
    walk on."""
    rb = robustness_bench()
    config = rb.walking_config("g1", sim="lip")
    bounds = rb.push_bounds(config, G1_START_S)
    bound = bounds["first"]["swing_uncrossed_torso"]
    assert bound < 1.5 < bounds["first"]["uncrossed_torso"]
    for kind in ("torso", "com", "uncrossed_torso", "uncrossed_com"):
        assert bounds["first"]["swing_" + kind] <= bounds["first"][kind] * (1.0 + 1e-9)
    lever = rb.lever_factor("g1")
    for recovery in ("next_step", "multi_step_timing"):
        base = rb.walking_config("g1", sim="lip", overrides=[f'control.recovery="{recovery}"'])
        mass = Session(base, backend="lip").mass

        def fell(scale: float, base=base, mass=mass) -> bool:
            pushed = rb.push_config(base, mass, scale, G1_START_S, lever)
            return Session(pushed, backend="lip").run(G1_START_S + rb.PUSH_S + 2.0).fell

        assert not fell(0.7 * bound), recovery
        assert all(fell(k * bound) for k in (1.05, 1.2, 1.5)), recovery


def test_the_g1s_swing_bound_is_the_bench_at_every_start() -> None:
    """swing_bound_at agrees with the numbers push_bounds hands the bench, in the push's scale."""
    rb = robustness_bench()
    config = rb.walking_config("g1", sim="lip")
    unit = rb.PAPER_FORCE_N * 33.341 / rb.PAPER_MASS_KG * rb.PUSH_S
    j = swing_bound_at(config, G1_START_S, rb.PUSH_S, math.pi / 2, backend="mujoco",
                       crossing=False)  # fmt: skip
    assert rb.push_bounds(config, G1_START_S)["first"]["swing_uncrossed_torso"] == pytest.approx(
        j / unit, rel=1e-3
    )
