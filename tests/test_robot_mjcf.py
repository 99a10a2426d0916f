"""Robot files with an MJCF model (issue 13): the G1's URDF written as MJCF by MuJoCo — motors
instead of joint torque limits, a free joint, the standing posture as a <key> — loads to the
same robot as the URDF (mass, CoM height, limits, locked joints) and walks in MuJoCo.

Independent checks: the URDF robot's numbers (built by another parser from another file),
MuJoCo's own subtree CoM and body masses of the model it builds from the edited MJCF.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pytest
from test_robot_files import PRESET, _urdf_mass, _walk

from dcmviz.config import load_preset
from dcmviz.robots import SIDES, RobotFileError, load_robot

ROBOT_FILE = """
name = "g1_mjcf"
description = "Unitree G1 29-dof, its URDF saved as MJCF by MuJoCo"

[model]
source = "file"
mjcf = "g1.xml"
reference_posture = "stand"      # a <key> of the MJCF

[joints]                          # the built-in g1's arms
keep = ["left_shoulder_pitch_joint", "left_shoulder_roll_joint", "left_shoulder_yaw_joint",
        "left_elbow_joint", "right_shoulder_pitch_joint", "right_shoulder_roll_joint",
        "right_shoulder_yaw_joint", "right_elbow_joint"]

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


def _g1_mjcf(tmp_path: Path) -> Path:
    """The built-in G1's URDF as MJCF (``MjSpec.to_xml``): mesh geoms dropped (their package://
    paths do not resolve; the inertials are the URDF's), a free joint on the pelvis, each leg and
    arm torque limit moved to a motor (gear 2, ctrlrange ± limit / 2), the built-in posture as
    the keyframe ``stand``.  Returns the robot file written next to it."""
    g1 = load_robot("g1").model
    root = ET.parse(g1.file.urdf_path).getroot()
    for link in root.findall("link"):
        for tag in ("visual", "collision"):
            for el in link.findall(tag):
                if el.find("geometry/mesh") is not None:
                    link.remove(el)
    text = ET.tostring(root, encoding="unicode").replace(
        "</robot>", '<mujoco><compiler fusestatic="false"/></mujoco></robot>'
    )
    spec = mujoco.MjSpec.from_string(text)
    spec.worldbody.first_body().add_freejoint(name="floating_base")
    for joint in spec.joints:
        if joint.type != mujoco.mjtJoint.mjJNT_HINGE:
            continue
        tau = float(joint.actfrcrange[1])
        joint.actfrclimited = mujoco.mjtLimited.mjLIMITED_FALSE
        act = spec.add_actuator(name=f"{joint.name}_motor", target=joint.name)
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.gear[0] = 2.0
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.ctrlrange = [-tau / 2, tau / 2]
    model = spec.compile()
    qpos = model.qpos0.copy()
    qpos[2] = 0.8
    for name, angle in g1.nominal.items():
        qpos[model.jnt_qposadr[model.joint(name).id]] = angle
    spec.add_key(name="stand", qpos=qpos)
    (tmp_path / "g1.xml").write_text(spec.to_xml(), encoding="utf-8")
    path = tmp_path / "g1_mjcf.toml"
    path.write_text(ROBOT_FILE, encoding="utf-8")
    return path


@pytest.mark.slow
def test_an_mjcf_robot_matches_its_urdf_and_walks(tmp_path):
    path = _g1_mjcf(tmp_path)
    urdf, mjcf = load_robot("g1").model, load_robot(str(path)).model
    assert mjcf.is_mjcf and not urdf.is_mjcf
    # the same robot: joints, locked posture, limits (torques from the motors: 2 × ctrlrange)
    assert mjcf.joint_names == urdf.joint_names and mjcf.legs == urdf.legs
    assert mjcf.locked.keys() == urdf.locked.keys()
    for name, angle in urdf.locked.items():
        assert mjcf.locked[name] == pytest.approx(angle, abs=1e-12)
    for name, lim in urdf.limits.items():
        got = mjcf.limits[name]
        assert (got.lower_rad, got.upper_rad) == pytest.approx((lim.lower_rad, lim.upper_rad))
        assert got.torque_nm == pytest.approx(lim.torque_nm, rel=1e-9)
    # derived numbers (MuJoCo writes 6 significant digits: µm and mg differences)
    d_u, d_m = urdf.derived, mjcf.derived
    assert d_m.mass_kg == pytest.approx(_urdf_mass(urdf.file.urdf_path) + 2e-4, abs=1e-5)
    assert d_m.mass_kg == pytest.approx(d_u.mass_kg, abs=1e-5)
    for key in ("com_height_m", "foot_spacing_m", "min_com_height_m", "max_com_height_m",
                "hip_sole_m", "leg_length_m", "max_step_length_m"):  # fmt: skip
        assert getattr(d_m, key) == pytest.approx(getattr(d_u, key), abs=1e-5), key
    np.testing.assert_allclose(mjcf.q_nominal, urdf.q_nominal, atol=1e-4)

    # MuJoCo, built from the same edited MJCF: its own CoM and masses agree with Pinocchio's
    robot = load_robot(str(path))
    mm = robot.mujoco.model
    assert mm.nu == len(robot.joint_names) and mm.njnt == 1 + len(robot.joint_names)
    assert float(mm.body_mass.sum()) == pytest.approx(d_m.mass_kg, abs=1e-9)
    data = mujoco.MjData(mm)
    data.qpos[:] = robot.mujoco.qpos_mj(robot.q_nominal)
    mujoco.mj_forward(mm, data)
    com = data.subtree_com[mm.body(robot.mujoco.root_body_name).id]
    soles = np.array([data.site_xpos[robot.mujoco.sole_sites[s]] for s in SIDES])
    assert com[2] - soles[:, 2].mean() == pytest.approx(d_m.com_height_m, abs=1e-9)
    np.testing.assert_allclose(soles[:, 2], 0.0, atol=1e-8)
    for name, lim in zip(robot.joint_names, robot.torque_limit, strict=True):
        np.testing.assert_allclose(mm.actuator_ctrlrange[mm.actuator(name).id], [-lim, lim])
    assert robot.mujoco.spec is not None

    # walks: the six-step preset of test_robot_files with this robot
    preset = tmp_path / "walk.toml"
    preset.write_text(PRESET.format(model=path.as_posix()), encoding="utf-8")
    config = load_preset(preset)
    fell, walker = _walk(config, 0.8 + 6 * 0.8 + 0.8 + 0.5)
    assert not fell
    assert walker.steps_completed == 6


def test_an_mjcf_robots_visual_meshes_sit_where_mujoco_puts_its_geoms(tmp_path):
    """The dashboard's and recorder's meshes of an MJCF robot: its geoms, posed like MuJoCo's
    own model of the file (the original MJCF, locked joints at their angles)."""
    from dcmviz.robots.pose import RobotPose
    from dcmviz.robots.visual import RobotVisual

    path = _g1_mjcf(tmp_path)
    rm = load_robot(str(path)).model
    q = rm.q_nominal
    joints = dict(rm.locked) | dict(zip(rm.joint_names, q[7:], strict=True))
    wxyz = np.r_[q[6], q[3:6]]
    visual = RobotVisual(str(path), rm)
    poses = visual.in_world(RobotPose(base_position=q[:3], base_wxyz=wxyz, joints=joints))
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "g1.xml"))
    data = mujoco.MjData(model)
    data.qpos[:7] = np.r_[q[:3], wxyz]
    for name, angle in joints.items():
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = angle
    mujoco.mj_forward(model, data)
    assert len(visual.meshes) == model.ngeom > 0
    # every mesh at one of MuJoCo's geoms (µm: MuJoCo's 6-digit XML)
    gap = np.linalg.norm(poses.position[:, None, :] - data.geom_xpos[None], axis=2)
    assert gap.min(axis=1).max() < 1e-5
    assert gap.min(axis=0).max() < 1e-5


def _mjcf_robot(tmp_path: Path, xml: str) -> str:
    (tmp_path / "r.xml").write_text(xml, encoding="utf-8")
    path = tmp_path / "r.toml"
    path.write_text(ROBOT_FILE.replace('"g1.xml"', '"r.xml"'), encoding="utf-8")
    return str(path)


LEG = """<body name="{side}_hip" pos="0 {y} -0.1"><joint name="{side}_hip_joint" axis="0 1 0"
range="-1 1" actuatorfrcrange="-50 50"/><inertial pos="0 0 0" mass="1" diaginertia=".01 .01 .01"/>
{extra}</body>"""

REFUSED = [
    # (what the model has, words the error must contain)
    ('<equality><joint joint1="left_hip_joint" joint2="right_hip_joint"/></equality>',
     ["model.mjcf", "equality constraint", "expected none"]),
    ('<worldbody><body name="box"><inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body>'
     "</worldbody>", ["model.mjcf", "2 bodies under <worldbody>", "expected"]),
    ("", ["feet.left.link", "left_ankle_roll_link", "no such body", "expected"]),
]  # fmt: skip


@pytest.mark.parametrize(("extra", "words"), REFUSED, ids=["equality", "two_roots", "no_foot"])
def test_an_mjcf_the_edit_cannot_carry_is_refused_naming_the_key(tmp_path, extra, words):
    legs = "".join(LEG.format(side=s, y=y, extra="") for s, y in (("left", 0.1), ("right", -0.1)))
    xml = (
        '<mujoco><worldbody><body name="pelvis"><freejoint/>'
        f'<inertial pos="0 0 0" mass="5" diaginertia=".1 .1 .1"/>{legs}</body></worldbody>'
        f"{extra}</mujoco>"
    )
    with pytest.raises(RobotFileError) as err:
        load_robot(_mjcf_robot(tmp_path, xml))
    for word in words:
        assert word in str(err.value), str(err.value)


@pytest.mark.parametrize(
    ("model", "words"),
    [
        ('urdf = "g1.urdf"\nmjcf = "g1.xml"', ["model.urdf and model.mjcf", "both", "exactly one"]),
        ('mjcf = "g1.urdf"', ["model.mjcf", "expected an MJCF file"]),
        ('urdf = "g1.xml"', ["model.urdf", "MJCF", "model.mjcf"]),
    ],
)
def test_the_model_table_takes_one_urdf_or_one_mjcf(tmp_path, model, words):
    path = tmp_path / "r.toml"
    path.write_text(ROBOT_FILE.replace('mjcf = "g1.xml"', model), encoding="utf-8")
    with pytest.raises(RobotFileError) as err:
        load_robot(str(path))
    for word in words:
        assert word in str(err.value), str(err.value)
