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


@pytest.mark.parametrize(
    "d, reach, landing, T",
    [
        (0.05, 0.0, 0.35, 1.0),  # a long push: the other foot lands in line while it lasts
        (0.08, -0.14, 0.12, 1.0),  # ... kept the minimum width inside the edge
        (0.1, 0.2, 0.3, 1.0),  # ... across, far out (a crossing robot)
        (0.1, 0.2, 0.5, 0.2),  # a short push: the crossed foot lands after it
        (0.1, -0.14, 0.12, 0.2),  # the stance-edge bound's case
    ],
)
def test_footstep_impulse_leaves_the_dcm_past_the_landing_foot_and_the_edge(
    d: float, reach: float, landing: float, T: float
) -> None:
    """Integrated LIP (RK4, the CoP on the edge d beyond ξ_0, the lever's b² + h/g): beyond the
    bound's impulse ξ is past the other foot's reach (d + reach) when it lands and past the edge
    when the push ends, the two conditions under which no footstep helps; 1 % less and one of
    them fails.  The bound's impulse meets one of them with equality."""
    m, b, lever = 33.0, 0.26, 0.28
    gain = b * b + lever / 9.81

    def dcm_at(impulse: float, t_end: float) -> float:
        F, n = impulse / T, 6000
        h = t_end / n
        # ẍ = (x − d)/b² + gain F/(m b²): the push as the CoP moved by gain F/m (its lever in)
        f = lambda t, y: np.array([y[1], (y[0] - d) / b**2 + (gain * F / m if t < T else 0) / b**2])  # noqa: E731,E501
        y, t = np.array([0.0, 0.0]), 0.0
        for _ in range(n):  # RK4 with the push's end on the grid (t_end a multiple of T or not)
            k1 = f(t, y)
            k2 = f(t + h / 2, y + h / 2 * k1)
            k3 = f(t + h / 2, y + h / 2 * k2)
            k4 = f(t + h, y + h * k3)
            y, t = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), t + h
        return y[0] + b * y[1]

    def lost(impulse: float) -> bool:
        return dcm_at(impulse, landing) > d + reach and dcm_at(impulse, T) > d

    J = footstep_impulse(d, reach, landing, m, b, T, lever)
    assert lost(1.01 * J) and not lost(0.99 * J)
    assert min(abs(dcm_at(J, landing) - (d + reach)), abs(dcm_at(J, T) - d)) < 1e-4


def test_for_a_short_push_the_footstep_bound_is_the_stance_edge_bound() -> None:
    """Talos's point mass, 0.2 s at mid single support towards the stance foot, the feet kept
    the minimum width apart: the push is over before the ξ could outrun the landing foot, so the
    bound is the stance-edge bound; with crossed footsteps allowed it is higher."""
    config = Config().replace(sim={"backend": "lip"}, control={"observer": False})
    start = push_window(config, 4, 0.5)[0]
    edge = stance_edge_bound(config, 4, 0.5, 0.2, math.pi / 2)
    uncrossed = footstep_bound_at(config, start, 0.2, math.pi / 2, crossing=False)
    assert abs(uncrossed - edge) < 1e-9 * edge
    assert footstep_bound_at(config, start, 0.2, math.pi / 2) > 1.5 * edge
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
