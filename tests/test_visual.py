"""The shared robot visual model: meshes load, and a RobotPose places them where MuJoCo has the links."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from dcmviz.config import Config, load_preset
from dcmviz.robots import load_robot
from dcmviz.robots.pose import RobotPose
from dcmviz.session import Session

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    ("model", "config"),
    [
        ("talos", Config().replace(sim={"backend": "mujoco"})),
        ("g1", load_preset(ROOT / "presets" / "g1_walk.toml").replace(sim={"backend": "mujoco"})),
        # COLLADA meshes (pycollada): without it the dashboard drew nothing for Romeo
        (
            "romeo",
            load_preset(ROOT / "presets" / "romeo_walk.toml").replace(sim={"backend": "mujoco"}),
        ),
    ],
)
def test_meshes_sit_on_the_simulated_links(model: str, config: Config) -> None:
    """Mesh frames against MuJoCo's own forward kinematics of the same state (an independent
    model built from the edited URDF), after a second of walking."""
    visual = load_robot(model).visual
    assert len(visual.meshes) > 30
    for mesh in visual.meshes:
        assert mesh.vertices.shape[1] == 3 and len(mesh.faces) > 0
        assert mesh.faces.max() < len(mesh.vertices)
    session = Session(config)
    session.run(1.0)
    pose = session.tick().pose
    backend = session.backend
    mujoco.mj_kinematics(backend.model, backend.data)  # xpos of the current qpos
    links = backend.body_poses()
    poses = visual.in_world(pose)
    np.testing.assert_allclose(np.linalg.norm(poses.wxyz, axis=1), 1.0, atol=1e-12)
    # every visual of these URDFs sits at its link's origin (origin xyz = rpy = 0)
    checked = 0
    for i, mesh in enumerate(visual.meshes):
        if mesh.link not in links:  # a static link MuJoCo fused into its parent
            continue
        p, q = links[mesh.link]
        np.testing.assert_allclose(poses.position[i], p, atol=1e-6, err_msg=mesh.name)
        assert min(np.abs(poses.wxyz[i] - q).max(), np.abs(poses.wxyz[i] + q).max()) < 1e-6
        checked += 1
    assert checked >= 20


def test_in_base_is_the_world_pose_without_the_base() -> None:
    visual = load_robot("talos").visual
    angle = 0.4
    c, s = np.cos(angle / 2), np.sin(angle / 2)
    joints = {"leg_left_4_joint": 0.7, "arm_right_2_joint": -0.3}
    pose = RobotPose(np.array([0.3, -0.2, 1.0]), np.array([c, 0.0, 0.0, s]), joints)
    world, base = visual.in_world(pose), visual.in_base(joints)
    R = np.array(
        [[np.cos(angle), -np.sin(angle), 0.0], [np.sin(angle), np.cos(angle), 0.0], [0, 0, 1]]
    )
    np.testing.assert_allclose(world.position, base.position @ R.T + pose.base_position, atol=1e-12)
    # bending the left knee moves the left ankle links and nothing else
    bent = visual.in_base({"leg_left_4_joint": 0.7})
    straight = visual.in_base({"leg_left_4_joint": 0.0})
    moved = {m.link for m, a, b in zip(visual.meshes, bent.position, straight.position, strict=True)
             if np.linalg.norm(a - b) > 1e-6}  # fmt: skip
    assert moved == {"leg_left_5_link", "leg_left_6_link"}  # the shank rotates about its origin


def test_a_mesh_no_reader_can_read_is_left_out_with_a_warning(monkeypatch) -> None:
    """A robot file whose meshes include a format trimesh cannot read here (Romeo's COLLADA
    without pycollada raised ImportError and the dashboard drew nothing at all): the robot is
    built without those meshes and one warning names the files and why."""
    import dcmviz.robots.visual as visual_module

    robot = load_robot("talos")
    full = robot.visual.meshes
    read = visual_module._mesh_of

    def failing(geometry):
        if "arm" in str(geometry.meshPath):
            raise ImportError("missing `pip install somereader`")
        return read(geometry)

    monkeypatch.setattr(visual_module, "_mesh_of", failing)
    with pytest.warns(UserWarning, match=r"visual meshes could not be read.*somereader") as caught:
        partial = visual_module.RobotVisual("talos", robot.model)
    arms = [m for m in full if any("arm" in a for a in m.ancestors[:1]) or "arm" in m.link]
    assert 0 < len(partial.meshes) < len(full)
    assert len(full) - len(partial.meshes) >= len(arms) > 0
    assert len(caught) == 1
    session = Session(Config().replace(sim={"backend": "mujoco"}))
    session.run(0.01)
    poses = partial.in_world(session.tick().pose)
    kept = [i for i, m in enumerate(full) if m.name in {p.name for p in partial.meshes}]
    np.testing.assert_allclose(
        poses.position, robot.visual.in_world(session.tick().pose).position[kept]
    )


@pytest.mark.parametrize("model", ["talos", "g1"])
def test_display_meshes_are_decimated_and_keep_their_shapes(model: str, monkeypatch) -> None:
    """The visual meshes are a display's level of detail: about DISPLAY_FACES triangles for a
    robot whose files have far more (headless Chromium's software WebGL spends ~1.3 µs a
    triangle per frame, and every change in the page waits for a frame), every mesh keeping
    its shape.  Checked against the same meshes read in full, by surface samples both ways:
    95 % of the decimated surface lies within 12 mm of the full one (no spikes: at
    fast_simplification's default aggression the G1's fingers collapsed into them) and 95 % of
    the full surface within 12 mm of the decimated one (no part lost); 12 mm is ~3 pixels of a
    1600 × 900 view at 3 m."""
    import trimesh
    from scipy.spatial import cKDTree

    import dcmviz.robots.visual as visual_module

    path = load_robot(model).model.file.model_path
    budget = visual_module.DISPLAY_FACES
    _, shown, _, _ = visual_module._read_visuals(path)
    monkeypatch.setattr(visual_module, "DISPLAY_FACES", 10**9)
    _, full, _, _ = visual_module._read_visuals(path)
    n_shown, n_full = (sum(len(m.faces) for m in ms) for ms in (shown, full))
    assert n_full > 4 * budget  # 159 k (Talos), 290 k (G1)
    assert n_shown <= 1.6 * budget  # a few meshes stop short of their share (G1: 36 k)
    assert [m.name for m in shown] == [m.name for m in full]
    for a, b in zip(full, shown, strict=True):
        dense = [trimesh.Trimesh(m.vertices, m.faces, process=False) for m in (a, b)]
        for src, dst in ((dense[1], dense[0]), (dense[0], dense[1])):
            near = cKDTree(trimesh.sample.sample_surface(dst, 20_000, seed=1)[0])
            d = near.query(trimesh.sample.sample_surface(src, 2_000, seed=2)[0])[0]
            assert np.percentile(d, 95) < 0.012, (a.name, len(a.faces), len(b.faces))
