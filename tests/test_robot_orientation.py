"""A robot file's reference posture keeps its base orientation (SRDF ``root_joint``), the loader
turns a robot that faces −x to face +x and stands it on flat soles; mirrored feet are refused
naming what is wrong; a point-mass link gets an inertia MuJoCo takes (issue 22, item 6).

Checked independently: the soles' world placement in the standing posture from Pinocchio's own
forward kinematics, the facing from the left sole lying on +y of the right one, the base's
standing orientation against MuJoCo's simulation of the robot standing for a second.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from dcmviz.robots import SIDES, RobotFileError, example_robot_data_dir, load_robot

ICUB = """
name = "icub"
description = "IIT iCub from example-robot-data, written from docs/robots.md"

[model]
urdf = "icub_description/robots/icub_reduced.urdf"
srdf = "icub_description/srdf/icub.srdf"
reference_posture = "half_sitting"

[feet.left]
link = "l_sole"
size = [0.12, 0.06]

[feet.right]
link = "r_sole"
size = [0.12, 0.06]

[bodies]
torso = "chest"

[standing]
com_height_m = 0.44
"""


def _write(tmp_path: Path, text: str, name: str) -> str:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return str(path)


def _soles(robot) -> dict[str, pin.SE3]:
    model = robot.model.pin_model
    data = model.createData()
    pin.framesForwardKinematics(model, data, robot.model.q_nominal)
    return {s: data.oMf[robot.sole_frames[s]].copy() for s in SIDES}


def _assert_stands_facing_x(robot, spacing: float) -> None:
    soles = _soles(robot)
    for s in SIDES:
        rotation = soles[s].rotation
        np.testing.assert_allclose(rotation[:, 2], [0.0, 0.0, 1.0], atol=1e-6)  # flat
        assert rotation[0, 0] > math.cos(math.radians(20))  # its x axis forward (+x)
        assert abs(soles[s].translation[2]) < 1e-6  # on the floor
    across = soles["left"].translation - soles["right"].translation
    assert across[1] == pytest.approx(spacing, abs=0.02) and abs(across[0]) < 0.01
    assert robot.spec.foot_spacing_m == pytest.approx(across[1], abs=1e-9)


def test_icub_faces_x_as_its_srdf_turns_its_base(tmp_path) -> None:
    """iCub's ``half_sitting`` turns the base by π about z (root_link's x points backwards): kept,
    the feet come out on the correct sides (was: refused with a foot spacing of −0.213 m)."""
    robot = load_robot(_write(tmp_path, ICUB, "icub.toml"))
    _assert_stands_facing_x(robot, 0.21)
    base = pin.XYZQUATToSE3(robot.model.q_nominal[:7]).rotation
    assert base[0, 0] < -0.99  # the base turned by π, as the SRDF says
    np.testing.assert_allclose(robot.base_offset, base, atol=1e-3)
    assert robot.spec.mass_kg == pytest.approx(28.35, abs=0.01)


def test_a_robot_facing_minus_x_is_turned_to_face_x(tmp_path) -> None:
    """Talos's SRDF rewritten to turn the base by π: the loader turns the robot back; the walking
    numbers are Talos's, and the base's standing orientation is the identity again."""
    robots = Path(example_robot_data_dir())
    srdf = ET.parse(robots / "talos_data/srdf/talos.srdf")
    for state in srdf.getroot().iter("group_state"):
        if state.get("name") == "half_sitting":
            for joint in state.iter("joint"):
                if joint.get("name") == "root_joint":
                    joint.set("value", "0 0 1.0 0 0 1 0")
    srdf.write(tmp_path / "talos_turned.srdf")
    urdf = robots / "talos_data/robots/talos_reduced.urdf"
    text = (
        (Path(__file__).parents[1] / "dcmviz/robots/data/talos.toml")
        .read_text(encoding="utf-8")
        .replace('name = "talos"', 'name = "talos_turned"')
        .replace('source = "example-robot-data"', 'source = "file"')
        .replace('urdf = "talos_data/robots/talos_reduced.urdf"', f'urdf = "{urdf}"')
        .replace('srdf = "talos_data/srdf/talos.srdf"', 'srdf = "talos_turned.srdf"')
    )
    turned = load_robot(_write(tmp_path, text, "talos_turned.toml"))
    talos = load_robot("talos")
    _assert_stands_facing_x(turned, 0.17)
    assert turned.base_offset is None  # facing +x with an upright base: the identity
    np.testing.assert_allclose(turned.model.q_nominal, talos.model.q_nominal, atol=1e-6)
    for key, value in vars(talos.model.derived).items():
        got = getattr(turned.model.derived, key)
        assert got == (pytest.approx(value, abs=1e-6) if isinstance(value, float) else value), key


def test_mirrored_feet_are_refused_saying_so(tmp_path) -> None:
    text = ICUB.replace('link = "l_sole"', 'link = "@L"').replace(
        'link = "r_sole"', 'link = "l_sole"'
    )
    path = _write(tmp_path, text.replace('"@L"', '"r_sole"'), "icub_mirrored.toml")
    with pytest.raises(RobotFileError) as err:
        load_robot(path)
    message = str(err.value)
    assert "feet.left.link = 'r_sole'" in message and "mirrored" in message, message


def test_a_malformed_root_joint_is_refused(tmp_path) -> None:
    robots = Path(example_robot_data_dir())
    srdf = (robots / "icub_description/srdf/icub.srdf").read_text(encoding="utf-8")
    (tmp_path / "bad.srdf").write_text(
        srdf.replace('value="0. 0. 0.60 0. 0. 1. 0."', 'value="0 0 0.6 0 0 3 0"'), encoding="utf-8"
    )
    text = ICUB.replace(
        'srdf = "icub_description/srdf/icub.srdf"', f'srdf = "{tmp_path / "bad.srdf"}"'
    )
    with pytest.raises(RobotFileError, match="root_joint"):
        load_robot(_write(tmp_path, text, "icub_bad.toml"))


@pytest.mark.slow
def test_icub_stands_in_mujoco_with_its_base_as_it_stands(tmp_path) -> None:
    """One second standing in MuJoCo under the whole-body QP: the base keeps its standing
    orientation (turned by π; a QP holding it at the identity would spin the robot round)."""
    from dcmviz.sim.mujoco_sim import MujocoBackend
    from dcmviz.walker.state import FootTarget, WalkerCommand

    robot = load_robot(_write(tmp_path, ICUB, "icub.toml"))
    backend = MujocoBackend(robot)
    state = backend.reset()
    weight = np.array([0.0, 0.0, robot.mass * 9.81])
    command = WalkerCommand(
        t=0.0, support={s: True for s in SIDES},
        feet={s: FootTarget(state.feet[s].copy()) for s in SIDES}, swing_side=None,
        com_force=np.zeros(3), contact_force=weight, xi=state.com, xi_ref=state.com,
        xi_adj=state.com, v_ref=state.com, v_cmd=state.com, f_hat=np.zeros(3),
    )  # fmt: skip
    for _ in range(500):
        state = backend.step(command)
    assert not backend.fell()
    _, wxyz = backend.base_pose()
    w, x, y, z = wxyz
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    assert abs(abs(yaw) - math.pi) < math.radians(3)
    np.testing.assert_allclose(
        state.com[:2], 0.5 * (state.feet["left"] + state.feet["right"])[:2], atol=0.03
    )


ICUB_STAIRS = """
[robot]
model = "{model}"
[gait]
mode = "plan"
n_steps = 12
step_length = 0.15
step_width = 0.211
t_ss = 0.7
t_ds = 0.2
[dcm]
b = 0.212
[control]
max_step_adjustment = 0.15
[sim]
backend = "mujoco"
duration = 14.0
[terrain.stairs]
start = 0.075
rise = {rise}
run = 0.15
count = 10
"""


@pytest.mark.slow
def test_icub_climbs_the_stairs_its_derived_step_height_allows(tmp_path) -> None:
    """iCub from a file: its knees (28 of their 30 N m standing) let its CoM down 1 cm, and on
    stairs the leg on the lower tread reaches down half the rise further, so its derived step
    height is 2 × 1 cm, not 0.18 × its leg (0.086 m, which it claimed before).  In MuJoCo it
    climbs ten 0.01 and 0.02 m stairs; at 0.03 m (where it fell before, unwarned) the
    feasibility check now says the step is out of its reach."""
    from dcmviz.config import loads_preset
    from dcmviz.gait import Planner
    from dcmviz.gait.feasibility import check_plan
    from dcmviz.session import Session

    path = _write(tmp_path, ICUB, "icub.toml")
    spec = load_robot(path).spec
    assert spec.max_step_height_m == pytest.approx(
        2 * (spec.com_height_m - spec.min_com_height_m), abs=1e-9
    )
    assert spec.max_step_height_m < 0.025
    for rise in (0.01, 0.02):
        config = loads_preset(ICUB_STAIRS.format(model=path, rise=rise))
        session = Session(config)
        session.run(config.sim.duration, stop_on_fall=True)
        assert not session.fell and session.steps_completed == 12, rise
    config = loads_preset(ICUB_STAIRS.format(model=path, rise=0.03))
    plan = Planner.of(config, spec).first()
    assert any("gait.step_height" == w.setting for w in check_plan(plan, spec, config))
