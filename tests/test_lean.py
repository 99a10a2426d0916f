"""How hard the legs lean against a sideways pull on one foot (dcmviz.robots.lean, issue 22): the
posture is what it claims (forward kinematics on fresh data), no posture found by an independent
optimiser leans further, the joint it names is the one that binds, and in a MuJoCo walk under a
pull that joint reaches its range where the static bound says it would."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from helpers import locked_arms_g1, robustness_bench
from scipy.optimize import minimize

from dcmviz.robots import load_robot
from dcmviz.robots.feet import OTHER
from dcmviz.robots.lean import LIFT_M, SOLE_GAP_WIDTHS, lean_reach


def _roll(robot, q) -> float:
    data = robot.pin_model.createData()
    pin.forwardKinematics(robot.pin_model, data, robot.q_nominal)
    nominal = data.oMi[1].rotation.copy()
    pin.forwardKinematics(robot.pin_model, data, q)
    r = data.oMi[1].rotation @ nominal.T
    return float(np.arctan2(r[2, 1], r[2, 2]))


@pytest.mark.parametrize("name", ["talos", "g1"])
@pytest.mark.parametrize("stance", ["right", "left"])
@pytest.mark.parametrize("trunk_roll", [0.0, 0.3])
def test_the_lean_posture_is_what_it_claims(name, stance, trunk_roll):
    """Forward kinematics on fresh data: the stance sole where it stood, flat; the other sole
    lifted and on its own side; every joint in its range; the CoM at the standing height and as
    far outboard as reported; the base rolled as asked; the named joints at a range end; the
    pull it holds (outboard + a_y) / z_p."""
    robot = load_robot(name)
    model = robot.pin_model
    lean = lean_reach(robot, trunk_roll, stance)
    data = model.createData()
    pin.framesForwardKinematics(model, data, robot.q_nominal)
    sole = data.oMf[robot.sole_frames[stance]].copy()
    pin.framesForwardKinematics(model, data, lean.q)
    placed = data.oMf[robot.sole_frames[stance]]
    np.testing.assert_allclose(placed.translation, sole.translation, atol=1e-6)
    np.testing.assert_allclose(placed.rotation, sole.rotation, atol=1e-6)
    other = data.oMf[robot.sole_frames[OTHER[stance]]].translation - sole.translation
    outboard = -1.0 if stance == "right" else 1.0
    assert other[2] >= LIFT_M - 1e-6
    assert -outboard * other[1] >= SOLE_GAP_WIDTHS * robot.foot_width - 1e-6
    joints = lean.q[7:]
    assert np.all(joints >= model.lowerPositionLimit[7:] - 1e-9)
    assert np.all(joints <= model.upperPositionLimit[7:] + 1e-9)
    com = pin.centerOfMass(model, data, lean.q)
    assert com[2] - sole.translation[2] == pytest.approx(robot.com_height, abs=1e-6)
    assert outboard * (com[1] - sole.translation[1]) == pytest.approx(lean.com_outboard_m, abs=1e-9)
    assert _roll(robot, lean.q) == pytest.approx(-outboard * trunk_roll, abs=0.01)
    assert lean.binding  # something stops the lean
    for joint in lean.binding:
        i = model.joints[model.getJointId(joint)].idx_q
        assert (
            min(lean.q[i] - model.lowerPositionLimit[i], model.upperPositionLimit[i] - lean.q[i])
            <= 1e-3
        )
    assert lean.pull_fraction == pytest.approx(
        (lean.com_outboard_m + robot.foot_width / 2)
        / (robot.com_height + robot.push_lever_m("torso"))
    )


def test_no_posture_found_by_another_optimiser_leans_the_g1_further():
    """SLSQP (scipy, finite differences) on the same problem — the stance sole fixed, the CoM
    height and the base's orientation held, the other sole lifted and aside, the joints' ranges —
    started from the standing posture and from lean_reach's, gets the G1's CoM no further
    outboard than lean_reach (1 mm), and from the standing posture within 5 mm of it."""
    robot = load_robot("g1")
    model = robot.pin_model
    data = model.createData()
    lean = lean_reach(robot, 0.0, "right")
    pin.framesForwardKinematics(model, data, robot.q_nominal)
    sole = data.oMf[robot.sole_frames["right"]].copy()
    pin.framesForwardKinematics(model, data, lean.q)
    base = data.oMi[1].rotation.copy()  # lean_reach's base orientation (its roll ≈ 0)
    q0 = robot.q_nominal
    lo, hi = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]

    def state(v):
        q = pin.integrate(model, q0, v)
        pin.framesForwardKinematics(model, data, q)
        return q, pin.centerOfMass(model, data, q)

    def outboard(v):
        _, com = state(v)
        return com[1] - sole.translation[1]  # minimised: the CoM towards -y, right's outboard

    def equalities(v):
        q, com = state(v)
        placed = data.oMf[robot.sole_frames["right"]]
        return np.r_[
            placed.translation - sole.translation,
            pin.log3(placed.rotation @ sole.rotation.T),
            com[2] - sole.translation[2] - robot.com_height,
            pin.log3(data.oMi[1].rotation @ base.T),  # upright, facing the walk
        ]

    def inequalities(v):
        q, _ = state(v)
        other = data.oMf[robot.sole_frames["left"]].translation - sole.translation
        return np.r_[
            other[2] - LIFT_M, other[1] - SOLE_GAP_WIDTHS * robot.foot_width, q[7:] - lo, hi - q[7:]
        ]

    constraints = [{"type": "eq", "fun": equalities}, {"type": "ineq", "fun": inequalities}]
    reached = []
    for start in (np.zeros(model.nv), pin.difference(model, q0, lean.q)):
        result = minimize(outboard, start, method="SLSQP", constraints=constraints,
                          options={"maxiter": 300, "ftol": 1e-10})  # fmt: skip
        assert np.abs(equalities(result.x)).max() < 1e-5
        assert inequalities(result.x).min() > -1e-5
        reached.append(-outboard(result.x))
    assert max(reached) <= lean.com_outboard_m + 1e-3, (reached, lean.com_outboard_m)
    assert reached[0] >= lean.com_outboard_m - 5e-3, (reached, lean.com_outboard_m)


def test_the_g1s_ankle_roll_range_is_what_stops_its_lean():
    """The G1 upright on its right foot: the right ankle roll (±0.26 rad) is at its range; with
    that range widened to ±0.6 rad the CoM leans more than twice as far, while widening the
    knee's range (not binding) changes nothing."""
    robot = load_robot("g1")
    lean = lean_reach(robot, 0.0, "right")
    assert "right_ankle_roll_joint" in lean.binding
    wide = lean_reach(robot, 0.0, "right", ranges={"right_ankle_roll_joint": (-0.6, 0.6)})
    assert wide.com_outboard_m > 2.0 * lean.com_outboard_m
    knee = robot.pin_model.joints[robot.pin_model.getJointId("right_knee_joint")].idx_q
    lo, hi = robot.pin_model.lowerPositionLimit[knee], robot.pin_model.upperPositionLimit[knee]
    same = lean_reach(robot, 0.0, "right", ranges={"right_knee_joint": (lo - 0.3, hi + 0.3)})
    assert same.com_outboard_m == pytest.approx(lean.com_outboard_m, abs=1e-4)


def test_walking_under_a_pull_the_g1_meets_the_range_the_bound_names(tmp_path):
    """MuJoCo, the bench's G1 gait, the G1 with its arms locked: unpulled, the right ankle roll
    keeps ≥ 0.08 rad of its range in right single support; under a pull ramped to 10 % of m g
    towards +y (above the 7.4 % it holds standing upright on one foot) it reaches the end of its
    range on the foot away from the pull (within 0.01 rad), as the static bound says it must.
    With its arms (the built-in G1) the bound is 10.7 %: they counterweigh the pull."""
    from dcmviz.session import Session

    rb = robustness_bench()
    assert 100 * lean_reach(load_robot("g1"), 0.0, "right").pull_fraction > 10.0
    model_file = locked_arms_g1(tmp_path)
    robot = load_robot(model_file)
    assert 100 * lean_reach(robot, 0.0, "right").pull_fraction < 10.0
    model = robot.pin_model
    joint = model.getJointId("right_ankle_roll_joint")
    lowest = model.lowerPositionLimit[model.joints[joint].idx_q]
    room = {}
    for level in (0.0, 10.0):
        config = rb.pull_config(rb.walking_config(model_file), robot.mass, level, 1.0)
        session = Session(config, backend="mujoco")
        scene = session.backend.model
        address = scene.jnt_qposadr[scene.joint("right_ankle_roll_joint").id]
        angles = []
        while session.t < rb.PULL_START_S + rb.PULL_RAMP_S:  # (10 % reached at its end)
            command = session.step()
            assert not session.metrics.fell
            if command.swing_side == "left" and session.t > 4.0:  # right single support
                angles.append(session.backend.data.qpos[address])
        room[level] = min(angles) - lowest
    assert room[0.0] >= 0.08, room
    assert room[10.0] <= 0.01, room


def test_the_robot_report_names_the_bound_and_the_joint(capsys):
    """``python -m dcmviz.robots g1`` ends with the pull the legs hold on one foot, upright and
    with the trunk rolled 0.3 rad, and the stance leg's joint that stops the lean."""
    from dcmviz.robots.__main__ import main

    assert main(["g1"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    robot = load_robot("g1")
    upright, rolled = (100 * lean_reach(robot, r, "right").pull_fraction for r in (0.0, 0.3))
    assert f"{upright:.1f} % of m g upright" in last
    assert f"{rolled:.1f} % of m g with the trunk rolled 0.3 rad" in last
    assert last.endswith("the lean stops at right_ankle_roll_joint")
