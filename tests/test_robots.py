"""Robot models: robot files vs loaded models, MuJoCo ⇄ Pinocchio maps (independent checks)."""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from dcmviz.robots import SIDES, example_robot_data_dir, load_robot

ROBOTS = ("talos", "g1", "romeo")


def test_unknown_robot_is_refused():
    with pytest.raises(ValueError, match="talos, g1, romeo"):
        load_robot("atlas")


@pytest.mark.parametrize("name", ROBOTS)
def test_spec_matches_models(name):
    robot = load_robot(name)
    spec = load_robot(name).spec
    # Pinocchio vs MuJoCo, each computed by its own library
    data = mujoco.MjData(robot.mujoco.model)
    data.qpos[:] = robot.mujoco.qpos_mj(robot.q_nominal)
    mujoco.mj_forward(robot.mujoco.model, data)
    root = robot.mujoco.model.body(robot.mujoco.root_body_name).id
    mj_mass = robot.mujoco.model.body_subtreemass[root]
    pm = robot.pin_model
    pd = pm.createData()
    pin_com = pin.centerOfMass(pm, pd, robot.q_nominal)
    assert pin.computeTotalMass(pm) == pytest.approx(mj_mass, rel=1e-9)
    np.testing.assert_allclose(pin_com, data.subtree_com[root], atol=1e-9)
    # the table: mass, CoM height above the soles, spacing
    assert mj_mass == pytest.approx(spec.mass_kg, rel=0.01)
    sole_z = np.mean([data.site_xpos[robot.mujoco.sole_sites[s]][2] for s in SIDES])
    assert data.subtree_com[root][2] - sole_z == pytest.approx(spec.com_height_m, abs=0.01)
    spacing = (
        data.site_xpos[robot.mujoco.sole_sites["left"]][1]
        - data.site_xpos[robot.mujoco.sole_sites["right"]][1]
    )
    assert spacing == pytest.approx(spec.foot_spacing_m, abs=0.01)
    # soles flat on the floor, centred at x = 0
    for s in SIDES:
        np.testing.assert_allclose(
            data.site_xpos[robot.mujoco.sole_sites[s]][[0, 2]], 0.0, atol=1e-6
        )
        np.testing.assert_allclose(
            data.site_xmat[robot.mujoco.sole_sites[s]].reshape(3, 3)[2, 2], 1.0, atol=1e-3
        )


def test_foot_size_matches_urdf_collision_geometry():
    """Talos: the box of talos_reduced_box.urdf; G1: the extent of the 4 foot spheres."""
    root = ET.parse(
        os.path.join(example_robot_data_dir(), "talos_data/robots/talos_reduced_box.urdf")
    ).getroot()
    link = next(li for li in root.iter("link") if li.get("name") == "leg_left_6_link")
    boxes = [c.find("geometry/box") for c in link.findall("collision")]
    size = [float(v) for v in next(b for b in boxes if b is not None).get("size").split()]
    assert load_robot("talos").spec.foot_length_m == pytest.approx(size[0])
    assert load_robot("talos").spec.foot_width_m == pytest.approx(size[1])
    root = ET.parse(
        os.path.join(example_robot_data_dir(), "g1_description/urdf/g1_29dof_rev_1_0.urdf")
    ).getroot()
    link = next(li for li in root.iter("link") if li.get("name") == "left_ankle_roll_link")
    xyz = np.array(
        [[float(v) for v in c.find("origin").get("xyz").split()] for c in link.findall("collision")]
    )
    assert np.ptp(xyz[:, 0]) == pytest.approx(load_robot("g1").spec.foot_length_m, abs=0.005)
    assert np.ptp(xyz[:, 1]) == pytest.approx(load_robot("g1").spec.foot_width_m, abs=0.005)
    # Romeo: the SRDF's foot size (0.1935 × 0.121 m) without the toe tip of the collision mesh
    srdf = ET.parse(
        os.path.join(example_robot_data_dir(), "romeo_description/srdf/romeo.srdf")
    ).getroot()
    size = srdf.find("specificities/feet/left/size")
    assert load_robot("romeo").spec.foot_width_m == pytest.approx(
        float(size.get("width")), abs=0.002
    )
    assert load_robot("romeo").spec.foot_length_m == pytest.approx(
        float(size.get("height")), abs=0.03
    )


@pytest.mark.parametrize("name", ROBOTS)
def test_joint_maps_round_trip_random_configuration(name):
    robot = load_robot(name)
    rng = np.random.default_rng(0)
    pm, pd = robot.pin_model, robot.pin_model.createData()
    q = pin.randomConfiguration(pm, -np.ones(pm.nq), np.ones(pm.nq))
    v = rng.normal(size=pm.nv)
    qpos = robot.mujoco.qpos_mj(q)
    qvel = robot.mujoco.qvel_mj(q, v)
    np.testing.assert_allclose(robot.mujoco.q_pin(qpos), q, atol=1e-12)
    np.testing.assert_allclose(robot.mujoco.v_pin(qpos, qvel), v, atol=1e-12)
    m = robot.mujoco.model
    data = mujoco.MjData(m)
    data.qpos[:], data.qvel[:] = qpos, qvel
    mujoco.mj_forward(m, data)
    pin.forwardKinematics(pm, pd, q, v)
    pin.updateFramePlacements(pm, pd)
    vel = np.zeros(6)
    for s in SIDES:
        oMf = pd.oMf[robot.sole_frames[s]]
        site = robot.mujoco.sole_sites[s]
        np.testing.assert_allclose(oMf.translation, data.site_xpos[site], atol=1e-9)
        np.testing.assert_allclose(oMf.rotation, data.site_xmat[site].reshape(3, 3), atol=1e-9)
        # velocity: MuJoCo object velocity (world-aligned, [ang; lin]) vs Pinocchio LWA
        mujoco.mj_objectVelocity(m, data, mujoco.mjtObj.mjOBJ_SITE, site, vel, 0)
        pv = pin.getFrameVelocity(pm, pd, robot.sole_frames[s], pin.LOCAL_WORLD_ALIGNED)
        np.testing.assert_allclose(vel[3:], pv.linear, atol=1e-9)
        np.testing.assert_allclose(vel[:3], pv.angular, atol=1e-9)


@pytest.mark.parametrize("name", ROBOTS)
def test_dynamics_agree(name):
    """M (with armature) and h agree once MuJoCo's world-frame base velocity is mapped:
    v_pin = T v_mj with T = blockdiag(Rᵀ, I, I)  ⇒  M_mj = Tᵀ M T, h_mj = Tᵀ (h + M Ṫ v_mj),
    Ṫ v_mj = [-ω × v_lin; 0] in the base frame."""
    robot = load_robot(name)
    rng = np.random.default_rng(1)
    pm, pd = robot.pin_model, robot.pin_model.createData()
    q = robot.q_nominal.copy()
    q[7:] += rng.normal(scale=0.2, size=robot.nu)
    v = rng.normal(size=pm.nv)
    m = robot.mujoco.model
    data = mujoco.MjData(m)
    data.qpos[:], data.qvel[:] = robot.mujoco.qpos_mj(q), robot.mujoco.qvel_mj(q, v)
    mujoco.mj_forward(m, data)
    M_mj = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, data, M_mj)
    perm = np.r_[0:6, robot.mujoco.dof_adr]
    M_mj, h_mj = M_mj[np.ix_(perm, perm)], data.qfrc_bias[perm]
    T = np.eye(pm.nv)
    T[:3, :3] = pin.Quaternion(q[6], *q[3:6]).toRotationMatrix().T
    M = pin.crba(pm, pd, q)
    h = pin.nonLinearEffects(pm, pd, q, v)
    np.testing.assert_allclose(T.T @ M @ T, M_mj, atol=1e-8)
    tdot_v = np.zeros(pm.nv)
    tdot_v[:3] = -np.cross(v[3:6], v[:3])
    np.testing.assert_allclose(T.T @ (h + M @ tdot_v), h_mj, atol=1e-8)
