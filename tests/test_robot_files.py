"""Robot files (issue 13): a humanoid is one TOML file; bad files are refused naming the key.

The derived numbers are checked against independent computations: the mass against the URDF's
<mass> elements summed by hand, the CoM height and its place above the soles against MuJoCo's
subtree CoM, the torque limits against the URDF's <limit effort>, b's range against Δz = g b².
"""

from __future__ import annotations

import math
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pytest

from dcmviz import GRAVITY
from dcmviz.config import ConfigError, config_from_dict, load_preset
from dcmviz.robots import BUILTIN_ROBOTS, SIDES, RobotFileError, example_robot_data_dir, load_robot
from dcmviz.sim.mujoco_sim import MujocoBackend
from dcmviz.walker import Walker

G1_HANDS = "g1_description/urdf/g1_29dof_with_hand_rev_1_0.urdf"

# a humanoid that is not built in: the G1 with its dexterous hands (a different URDF, 14 more
# joints to lock, 1.5 kg more), copied next to its robot file, every walking number derived
ROBOT_FILE = """
name = "g1_hands"
description = "Unitree G1 with hands, from a URDF next to this file"

[model]
source = "file"
urdf = "g1_hands.urdf"

[posture]
left_hip_pitch_joint = -0.312
left_knee_joint = 0.669
left_ankle_pitch_joint = -0.363
right_hip_pitch_joint = -0.312
right_knee_joint = 0.669
right_ankle_pitch_joint = -0.363

[feet.left]
link = "left_ankle_roll_link"
offset = [0.035, 0.0, -0.035]
size = [0.17, 0.06]

[feet.right]
link = "right_ankle_roll_link"
offset = [0.035, 0.0, -0.035]
size = [0.17, 0.06]

[bodies]
torso = "torso_link"
pelvis = "pelvis"
"""

PRESET = """
name = "g1 with hands, six steps"

[robot]
model = "{model}"

[gait]
n_steps = 6
step_length = 0.12
step_width = 0.24
t_ss = 0.6
t_ds = 0.2
t_start = 0.8
t_stop = 0.8

[dcm]
b = 0.26

[control]
max_step_adjustment = 0.2
"""


def _write_robot(tmp_path: Path, text: str = ROBOT_FILE, name: str = "g1_hands.toml") -> Path:
    shutil.copy(Path(example_robot_data_dir()) / G1_HANDS, tmp_path / "g1_hands.urdf")
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _urdf_mass(path: str) -> float:
    root = ET.parse(path).getroot()
    return sum(float(m.get("value")) for m in root.iter("mass"))


def _walk(config, duration: float) -> tuple[bool, Walker]:
    backend = MujocoBackend(load_robot(config.robot.model))
    state = backend.reset()
    walker = Walker(config, backend.robot, mass=backend.mass, dt=backend.control_dt)
    walker.reset(state)
    while state.t < duration - 1e-9:
        force = np.zeros(3)
        for push in config.pushes:
            if push.start <= state.t < push.start + push.duration:
                force = force + np.asarray(push.force, float)
        if config.pushes:
            backend.set_external_force(config.pushes[0].body, force)
        state = backend.step(walker.step(state))
        if backend.fell():
            return True, walker
    return False, walker


@pytest.mark.slow
def test_a_robot_written_as_one_file_walks_six_steps(tmp_path):
    """Done-when of issue 13: robot file + preset in a temporary directory → six steps."""
    robot_path = _write_robot(tmp_path)
    preset = tmp_path / "walk.toml"
    preset.write_text(PRESET.format(model=robot_path.as_posix()), encoding="utf-8")
    config = load_preset(preset)
    assert config.robot.model == robot_path.as_posix()
    spec = load_robot(config.robot.model).spec
    assert spec.name == "g1_hands" and spec.name not in BUILTIN_ROBOTS
    # derived (nothing pinned): the URDF's masses (+ two 0.1 g sole links), b from the height
    assert spec.mass_kg == pytest.approx(_urdf_mass(str(tmp_path / "g1_hands.urdf")) + 2e-4)
    assert spec.mass_kg > load_robot("g1").spec.mass_kg + 1.0  # the hands
    assert spec.b_nominal_s == pytest.approx(math.sqrt(spec.com_height_m / GRAVITY))
    duration = 0.8 + 6 * 0.8 + 0.8 + 0.5
    fell, walker = _walk(config, duration)
    assert not fell
    assert walker.steps_completed == 6


@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_derived_numbers_match_independent_computations(name):
    rm = load_robot(name).model
    robot = load_robot(name)
    d = rm.derived
    added = sum(parent is not None for parent in rm.sole_parent.values())
    assert d.mass_kg == pytest.approx(_urdf_mass(rm.file.urdf_path) + added * 1e-4, rel=1e-9)
    # MuJoCo: CoM height above the soles and above their middle
    data = mujoco.MjData(robot.mujoco.model)
    data.qpos[:] = robot.mujoco.qpos_mj(robot.q_nominal)
    mujoco.mj_forward(robot.mujoco.model, data)
    com = data.subtree_com[robot.mujoco.model.body(robot.mujoco.root_body_name).id]
    soles = np.array([data.site_xpos[robot.mujoco.sole_sites[s]] for s in SIDES])
    assert com[2] - soles[:, 2].mean() == pytest.approx(d.com_height_m, abs=1e-9)
    np.testing.assert_allclose(com[:2], soles[:, :2].mean(axis=0), atol=1e-8)
    np.testing.assert_allclose(soles[:, 2], 0.0, atol=1e-8)
    # limits straight from the URDF
    joints = {j.get("name"): j for j in ET.parse(rm.file.urdf_path).getroot().findall("joint")}
    for name_j, limit in zip(robot.joint_names, robot.torque_limit, strict=True):
        el = joints[name_j].find("limit")
        assert limit == pytest.approx(float(el.get("effort")))
        assert rm.limits[name_j].lower_rad == pytest.approx(float(el.get("lower")))
        i = robot.mujoco.model.actuator(name_j).id
        np.testing.assert_allclose(robot.mujoco.model.actuator_ctrlrange[i], [-limit, limit])
    spec = rm.spec
    lo, hi = spec.b_range_s
    assert GRAVITY * lo**2 == pytest.approx(spec.min_com_height_m)
    assert GRAVITY * hi**2 == pytest.approx(spec.max_com_height_m)
    assert spec.min_com_height_m <= spec.com_height_m <= spec.max_com_height_m


def test_pinned_numbers_are_close_to_the_derived_ones():
    """Talos's file pins the numbers shipped before robots were files; the loader derives them
    independently (within 1 cm / 0.1 kg where the pin is a measurement, not a choice)."""
    d, s = load_robot("talos").model.derived, load_robot("talos").spec
    assert d.mass_kg == pytest.approx(s.mass_kg, abs=0.01)
    assert d.com_height_m == pytest.approx(s.com_height_m, abs=0.001)
    assert d.foot_spacing_m == pytest.approx(s.foot_spacing_m, abs=0.001)
    assert d.max_com_height_m == pytest.approx(s.max_com_height_m, abs=0.01)
    assert d.max_step_length_m == pytest.approx(s.max_step_length_m, abs=0.01)
    assert d.leg_length_m == pytest.approx(s.leg_length_m, abs=0.005)
    g1 = load_robot("g1").spec  # the hip–ankle distance at the (pinned) highest CoM, from the model
    d = load_robot("g1").model.derived
    assert g1.max_com_height_m - d.hip_below_com_m - d.ankle_above_sole_m == pytest.approx(
        g1.leg_length_m, abs=0.001
    )


def test_standing_posture_is_solved_for_a_requested_com_height(tmp_path):
    text = ROBOT_FILE.replace('name = "g1_hands"', 'name = "g1_low"') + (
        "\n[standing]\ncom_height_m = 0.62\n"
    )
    rm = load_robot(str(_write_robot(tmp_path, text, "g1_low.toml"))).model
    import pinocchio as pin

    pm, q = rm.pin_model, rm.q_nominal
    data = pm.createData()
    pin.framesForwardKinematics(pm, data, q)
    com = pin.centerOfMass(pm, data, q)
    soles = np.array([data.oMf[pm.getFrameId(f"{s}_sole_link")].translation for s in SIDES])
    assert com[2] - soles[:, 2].mean() == pytest.approx(0.62, abs=1e-8)
    np.testing.assert_allclose(com[:2], soles[:, :2].mean(axis=0), atol=1e-8)
    for s in SIDES:  # soles flat on the floor (as flat as in the reference posture: 0.3°)
        R = data.oMf[pm.getFrameId(f"{s}_sole_link")].rotation
        assert R[2, 2] == pytest.approx(1.0, abs=1e-3)
    assert rm.spec.com_height_m == pytest.approx(0.62, abs=1e-8)


BAD = [
    # (replace this, with this, words the error must contain)
    ('torso = "torso_link"', 'torso = "chest_link"', ["bodies.torso", "chest_link", "expected"]),
    (
        'link = "left_ankle_roll_link"',
        'link = "left_foot_link"',
        ["feet.left.link", "left_foot_link", "no such link", "expected"],
    ),
    (
        'link = "left_ankle_roll_link"',
        'link = "pelvis"',
        ["feet.left.link", "no leg found", "expected"],
    ),
    (
        'link = "right_ankle_roll_link"\noffset = [0.035, 0.0, -0.035]',
        'link = "right_ankle_roll_link"\noffset = [0.035, 0.0, 0.015]',
        ["feet", "do not touch the ground", "expected"],
    ),
    (
        'urdf = "g1_hands.urdf"',
        'urdf = "missing.urdf"',
        ["model.urdf", "missing.urdf", "not found"],
    ),
    ('urdf = "g1_hands.urdf"', 'urdf = "g1_hands.xml"', ["model.urdf", "MJCF", "expected"]),
    ("size = [0.17, 0.06]", "size = [0.17]", ["feet.left.size", "expected"]),
    ("[bodies]", "[bodys]", ["bodys", "unknown key"]),
    (
        "[feet.left]",
        "[controller]\nkp_feet = 3.0\n\n[feet.left]",
        ["controller", "kp_feet", "expected"],
    ),
    (
        "[posture]",
        "[posture]\nleft_knee_jont = 0.3",
        ["posture.left_knee_jont", "expected"],
    ),
    (
        "[bodies]",
        "[actuators]\ntorque_limits = { left_knee_jont = 100.0 }\n\n[bodies]",
        ["actuators.torque_limits", "left_knee_jont", "not an actuated joint", "expected"],
    ),
    (
        "[bodies]",
        "[actuators]\ntorque_limits = { left_knee_joint = -5.0 }\n\n[bodies]",
        ["actuators.torque_limits", "left_knee_joint = -5.0", "expected"],
    ),
    (
        "[bodies]",
        "[actuators]\ntorque_scale = 0.0\n\n[bodies]",
        ["actuators.torque_scale", "greater than 0"],
    ),
]


@pytest.mark.parametrize(("old", "new", "words"), BAD, ids=[b[1][:20] for b in BAD])
def test_a_bad_robot_file_is_refused_naming_the_key(tmp_path, old, new, words):
    assert old in ROBOT_FILE
    path = _write_robot(tmp_path, ROBOT_FILE.replace(old, new, 1), "bad.toml")
    with pytest.raises(RobotFileError) as err:
        load_robot(str(path))
    for word in words:
        assert word in str(err.value), str(err.value)
    # every entry point refuses it the same way: nothing half-loads
    with pytest.raises(ConfigError) as err:
        config_from_dict({"robot": {"model": str(path)}})
    assert "robot.model" in str(err.value) and words[0] in str(err.value)
    with pytest.raises(ValueError, match="robot.model"):
        load_robot(str(path))


def test_a_urdf_that_does_not_load_is_refused(tmp_path):
    path = _write_robot(tmp_path)
    (tmp_path / "g1_hands.urdf").write_text("<robot name='x'><link name='a'></robot>")
    with pytest.raises(RobotFileError) as err:
        load_robot(str(path))
    assert "model.urdf" in str(err.value) and "does not load" in str(err.value)


def test_preset_b_is_checked_against_the_robot_files_heights(tmp_path):
    path = str(_write_robot(tmp_path))
    spec = load_robot(path).spec
    lo, hi = spec.b_range_s
    assert config_from_dict({"robot": {"model": path}, "dcm": {"b": hi}}).dcm.b == hi
    with pytest.raises(ConfigError, match="dcm.b"):
        config_from_dict({"robot": {"model": path}, "dcm": {"b": hi + 1e-3}})


def test_robot_dropdown_lists_the_built_ins_and_the_presets_robot(tmp_path):
    from dcmviz.dashboard.sim_panel import robot_options

    path = str(_write_robot(tmp_path))
    config = config_from_dict({"robot": {"model": path}, "dcm": {"b": 0.26}})
    assert robot_options(config) == (*BUILTIN_ROBOTS, path)
    assert robot_options(config_from_dict({})) == BUILTIN_ROBOTS


@pytest.mark.slow
@pytest.mark.parametrize("preset", ["g1_push.toml", "romeo_push.toml"])
def test_lateral_push_scaled_to_the_robots_mass_is_survived(preset):
    """The paper's ±25 N on Toro (76 kg) scaled by mass: the same 0.33 m/s² on every robot."""
    config = load_preset(Path(__file__).resolve().parents[1] / "presets" / preset)
    mass = load_robot(config.robot.model).spec.mass_kg
    for push in config.pushes:
        assert abs(push.force[1]) == pytest.approx(25.0 * mass / 76.0, abs=0.05)
    fell, walker = _walk(config, config.sim.duration)
    assert not fell
    assert walker.steps_completed == config.gait.n_steps


def test_dashboard_shows_a_presets_robot_file_in_its_dropdown(tmp_path):
    """Loading a preset whose robot is a file adds it to the robot dropdown; the sliders, push
    bodies and the walk follow that robot."""
    import viser
    from helpers import free_port

    from dcmviz.config import Config
    from dcmviz.dashboard import Dashboard

    path = str(_write_robot(tmp_path))
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    dash = Dashboard(server, Config().replace(sim={"backend": "lip"}), start=False)
    try:
        dropdown = dash.controls.handles[("robot", "model")]
        assert tuple(dropdown.options) == BUILTIN_ROBOTS
        config = config_from_dict(
            {"robot": {"model": path}, "dcm": {"b": 0.26}, "gait": {"step_width": 0.24},
             "sim": {"backend": "lip"}}
        )  # fmt: skip
        assert dash.editor.apply_config(config)
        dash.loop.pump()
        assert tuple(dropdown.options) == (*BUILTIN_ROBOTS, path) and dropdown.value == path
        lo, hi = load_robot(path).spec.b_range_s
        b = dash.controls.handles[("dcm", "b")]
        assert lo - 5e-4 <= b.min < b.max <= hi + 5e-4  # the b slider spans the file's range
        assert dash.loop.session.config.robot.model == path
    finally:
        dash.stop()
        server.stop()


def test_controller_values_of_a_robot_file_reach_the_whole_body_qp(tmp_path):
    from dcmviz.sim.wbc import Gains, WholeBodyController

    text = ROBOT_FILE.replace('name = "g1_hands"', 'name = "g1_soft"') + (
        "\n[controller]\nkp_foot = 400.0\nfriction = 0.6\n"
    )
    robot = load_robot(str(_write_robot(tmp_path, text, "g1_soft.toml")))
    gains = WholeBodyController(robot).gains
    assert (gains.kp_foot, gains.friction) == (400.0, 0.6)
    assert gains.kd_foot == Gains().kd_foot  # the rest keep the defaults
    assert WholeBodyController(load_robot("g1")).gains == Gains()  # built-ins set none


def test_torque_limits_of_a_robot_file_reach_the_qp_and_mujocos_motors(tmp_path):
    """``[actuators] torque_limits`` replaces a joint's URDF effort and ``torque_scale`` then
    multiplies every actuated joint's: the robot's limits (the whole-body QP's bounds) equal the
    URDF's <limit effort> read by hand with those changes, and MuJoCo clamps each motor there
    (its ctrlrange and the joint's actuator-force range: MuJoCo's URDF import set the latter
    from the effort, so a replaced limit was clamped at the URDF's before)."""
    text = ROBOT_FILE.replace('name = "g1_hands"', 'name = "g1_strong"').replace(
        "[bodies]",
        "[actuators]\ntorque_limits = { left_knee_joint = 100.0 }\ntorque_scale = 1.5\n\n[bodies]",
    )
    robot = load_robot(str(_write_robot(tmp_path, text, "g1_strong.toml")))
    efforts = {
        j.get("name"): float(j.find("limit").get("effort"))
        for j in ET.parse(tmp_path / "g1_hands.urdf").getroot().iter("joint")
        if j.find("limit") is not None
    }
    expected = [1.5 * (100.0 if n == "left_knee_joint" else efforts[n]) for n in robot.joint_names]
    np.testing.assert_allclose(robot.torque_limit, expected, rtol=1e-12)
    model = MujocoBackend(robot).model
    for name, limit in zip(robot.joint_names, expected, strict=True):
        assert model.actuator(name).ctrlrange.tolist() == pytest.approx([-limit, limit])
        j = model.joint(name).id
        assert model.jnt_actfrclimited[j] == 1
        assert model.jnt_actfrcrange[j].tolist() == pytest.approx([-limit, limit])
