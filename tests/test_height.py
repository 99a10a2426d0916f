"""The legs' reach lowers the CoM (dcmviz.gait.height), checked against the robots' kinematics.

The closed form H(s) = H_max − D + sqrt(D² − s²) is compared with Pinocchio: the robot stands at
its highest walking CoM height, then takes a stride by rotating one hip forward and the other
back by θ (the ankles counter-rotate, the soles stay flat, the trunk upright); the CoM height
above the soles is computed from the model's masses and compared with H at the half-distance of
the soles.  A plan that asks for more walks lower, and says so.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import brentq

from dcmviz import GRAVITY
from dcmviz.config import Config
from dcmviz.gait import plan_from_config
from dcmviz.gait.feasibility import HEIGHT_TOLERANCE_M, check_plan
from dcmviz.gait.height import walk_height_m
from dcmviz.robots import load_robot

PITCH = {
    "talos": ("leg_{s}_3_joint", "leg_{s}_4_joint", "leg_{s}_5_joint"),
    "g1": ("{s}_hip_pitch_joint", "{s}_knee_joint", "{s}_ankle_pitch_joint"),
}


def _posture(robot, straighten: float, theta: float) -> tuple[float, float]:
    """(CoM height above the soles, half the soles' x distance) of a stride posture."""
    pm = robot.pin_model
    q = robot.q_nominal.copy()
    for side, sign in (("left", 1.0), ("right", -1.0)):
        hip, knee, ankle = (
            pm.joints[pm.getJointId(n.format(s=side))].idx_q for n in PITCH[robot.name]
        )
        q[knee] -= straighten
        q[hip] += 0.5 * straighten - sign * theta
        q[ankle] += 0.5 * straighten + sign * theta
    data = pm.createData()
    pin.framesForwardKinematics(pm, data, q)
    soles = np.array([data.oMf[f].translation for f in robot.sole_frames.values()])
    com = pin.centerOfMass(pm, data, q)
    return float(com[2] - soles[:, 2].mean()), 0.5 * abs(soles[0, 0] - soles[1, 0])


@pytest.mark.parametrize("name", ["talos", "g1"])
def test_walk_height_matches_the_kinematics(name):
    robot, spec = load_robot(name), load_robot(name).spec
    # straighten the knees until the CoM stands at the highest walking height
    a = brentq(lambda a: _posture(robot, a, 0.0)[0] - spec.max_com_height_m, -0.5, 0.6)
    for theta in (0.1, 0.2, 0.3):
        height, s = _posture(robot, a, theta)
        assert walk_height_m(spec, s) == pytest.approx(height, abs=0.008), theta
        if theta >= 0.2:
            assert height < spec.max_com_height_m - 0.009  # a stride lowers the CoM


def test_long_steps_at_the_top_height_walk_lower_and_say_so():
    spec = load_robot("talos").spec
    b = math.sqrt(spec.max_com_height_m / GRAVITY)
    config = Config().replace(
        robot={"model": "talos"}, gait={"step_length": 0.40, "step_width": 0.2}, dcm={"b": b}
    )
    plan = plan_from_config(config)
    z = plan.waypoints[:, 2]
    lowest = z.min()
    assert lowest < spec.max_com_height_m - 0.02  # the VRP dips while the feet are apart
    assert z[-1] == pytest.approx(spec.max_com_height_m, abs=1e-3)  # standing: as asked
    warnings = [w for w in check_plan(plan, spec, config) if w.setting == "dcm.b"]
    assert len(warnings) == 1 and f"{lowest:.3f} m" in warnings[0].message
    # short steps: within the 1 cm the humanoid tracks anyway, no warning
    short = Config().replace(robot={"model": "talos"}, gait={"step_length": 0.1}, dcm={"b": b})
    plan = plan_from_config(short)
    assert plan.waypoints[3:, 2].min() > spec.max_com_height_m - HEIGHT_TOLERANCE_M
    assert not [w for w in check_plan(plan, spec, short) if w.setting == "dcm.b"]
