"""The stance-edge bound of a push towards the stance foot (dcmviz.sweep.bounds)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from helpers import rk4

from dcmviz.config import Config, load_preset
from dcmviz.gait import plan_from_config
from dcmviz.session import Session
from dcmviz.sweep.bounds import edge_impulse, stance_edge_bound
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
