"""Terrain (issue 10, planning part): stairs and boxes, footsteps on treads, swing clearance."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from dcmviz.config import Config, ConfigError, loads_preset
from dcmviz.gait import plan_from_config
from dcmviz.gait.swing import EDGE_CLEARANCE_M, SwingTrajectory
from dcmviz.gait.terrain import Terrain, stairs_boxes
from dcmviz.robots import load_robot
from dcmviz.robots.feet import Footstep
from dcmviz.robots.geometry import sole_corners
from dcmviz.session import Session

STAIRS = """
[gait]
n_steps = 12
step_length = 0.30
t_ss = 0.9
t_ds = 0.3
[terrain.stairs]
start = 0.15
rise = {rise}
run = 0.30
count = 10
[sim]
backend = "lip"
"""


def stairs(rise: float) -> Config:
    return loads_preset(STAIRS.format(rise=rise))


def test_stairs_heights_against_a_direct_formula() -> None:
    terrain = Terrain(stairs_boxes(0.15, 0.15, 0.30, 10, 1.2, 1.5))
    rng = np.random.default_rng(0)
    xy = np.column_stack([rng.uniform(-1.0, 5.0, 2000), rng.uniform(-0.7, 0.7, 2000)])
    expected = np.where(
        (np.abs(xy[:, 1]) <= 0.6) & (xy[:, 0] >= 0.15) & (xy[:, 0] <= 0.15 + 9 * 0.3 + 1.8),
        0.15 * np.clip(np.floor((xy[:, 0] - 0.15) / 0.30) + 1, 0, 10),
        0.0,
    )
    np.testing.assert_allclose(terrain.height_at(xy), expected)


@pytest.mark.parametrize("rise", [0.15, -0.15])
def test_footsteps_take_the_tread_heights_and_sit_inside_treads(rise: float) -> None:
    config = stairs(rise)
    plan = plan_from_config(config)
    terrain = Terrain(stairs_boxes(0.15, rise, 0.30, 10, 1.2, 1.5))
    spec = load_robot("talos").spec
    for step in plan.steps:
        corners = sole_corners(step.position, step.yaw, spec.foot_length_m, spec.foot_width_m)
        heights = terrain.height_at(corners[:, :2] if corners.shape[1] > 2 else corners)
        assert np.ptp(heights) == 0.0  # no sole straddles an edge
        assert step.position[2] == pytest.approx(heights[0])
    z = [s.position[2] for s in plan.steps]
    assert z[9] == pytest.approx(1.5 if rise > 0 else 0.0)


def test_swing_clears_every_edge_by_the_stated_margin() -> None:
    terrain = Terrain(stairs_boxes(0.15, 0.15, 0.30, 10, 1.2, 1.5))
    spec = load_robot("talos").spec
    lift = Footstep("left", np.array([0.3, 0.085, 0.15]))
    touch = Footstep("left", np.array([0.9, 0.085, 0.45]))
    swing = SwingTrajectory.between(
        0.0, 0.9, lift, touch, terrain=terrain, sole=(spec.foot_length_m, spec.foot_width_m)
    )
    gx, gy = np.meshgrid(np.linspace(-0.5, 0.5, 7), np.linspace(-0.5, 0.5, 5))
    for t in np.linspace(0.02, 0.88, 400):
        p, _, _, yaw, _ = swing.sample(t)
        c, s = math.cos(yaw), math.sin(yaw)
        lx, ly = gx.ravel() * spec.foot_length_m, gy.ravel() * spec.foot_width_m
        pts = np.column_stack([p[0] + c * lx - s * ly, p[1] + s * lx + c * ly])
        under = terrain.height_at(pts)
        straddles = np.ptp(under) > 0.0  # the sole over an edge: clear it by the margin
        assert p[2] >= under.max() + (EDGE_CLEARANCE_M if straddles else 0.0) - 2e-3


def test_a_sole_landing_across_an_edge_is_warned_and_its_swing_stays_low() -> None:
    """Stairs whose treads do not sit under the footsteps (first riser at 0.125 m, 0.168 m steps
    and runs, iCub's 0.12 m soles): every sole lands across an edge.  The feasibility check says
    so for each footstep, naming terrain.stairs.start, and the swing's plateau stays at most the
    highest ground under its path plus the edge clearance and the apex: it asked for 15 m (the
    clearance of an edge under the landing sole, where the path's rise R - F → 0, divided by
    it), and the robot's swing foot flew up at 4 m/s.  The built-in terrain presets: no such
    warning, and no swing of theirs reaches that ceiling (it changes none of them)."""
    from pathlib import Path

    from dcmviz.config import load_preset
    from dcmviz.gait import Planner
    from dcmviz.gait.feasibility import check_plan
    from dcmviz.gait.swing import SWING_HEIGHT_M
    from dcmviz.gait.terrain import terrain_of

    config = loads_preset(
        STAIRS.replace("step_length = 0.30", "step_length = 0.168").format(rise=0.02)
        .replace("start = 0.15", "start = 0.125").replace("run = 0.30", "run = 0.168")
    )  # fmt: skip
    spec = dataclasses.replace(load_robot("talos").spec, foot_length_m=0.12)
    plan = Planner.of(config, spec).first()
    edges = [w for w in check_plan(plan, spec, config) if "across an edge" in str(w)]
    assert [w.step for w in edges] == list(range(len(edges))) and len(edges) >= 10
    assert all(w.setting == "terrain.stairs.start" for w in edges)
    terrain = terrain_of(config.terrain)
    sole = (spec.foot_length_m, spec.foot_width_m)
    lift = Footstep("left", np.array([0.0, 0.1, 0.0]))
    touch = Footstep("left", np.array([0.168, 0.1, 0.02]))
    swing = SwingTrajectory.between(0.0, 0.7, lift, touch, terrain=terrain, sole=sole)
    assert swing.top <= 0.02 + EDGE_CLEARANCE_M + SWING_HEIGHT_M + 1e-12
    assert swing.top >= 0.02 + SWING_HEIGHT_M  # (still above the step's own apex)
    root = Path(__file__).resolve().parents[1] / "presets"
    for name in ("stairs", "stairs_up", "stairs_down", "stairs_g1", "stepping_stones"):
        preset = load_preset(root / f"{name}.toml")
        preset_spec = load_robot(preset.robot.model).spec
        preset_plan = Planner.of(preset, preset_spec).first()
        assert not [w for w in check_plan(preset_plan, preset_spec, preset) if "across" in str(w)]
        ground = terrain_of(preset.terrain)
        soles = (preset_spec.foot_length_m, preset_spec.foot_width_m)
        last = dict(preset_plan.start_feet)
        for step in preset_plan.steps:  # each foot from where it stood to where it lands
            lift = last[step.side]
            top = SwingTrajectory.between(0.0, 0.7, lift, step, terrain=ground, sole=soles).top
            highest = max(lift.position[2], step.position[2])
            assert top < highest + EDGE_CLEARANCE_M + SWING_HEIGHT_M - 1e-9, name
            last[step.side] = step


@pytest.mark.parametrize("rise", [0.15, -0.15])
def test_point_mass_climbs_and_descends_ten_steps(rise: float) -> None:
    s = Session(stairs(rise), backend="lip")
    s.run(20.0)
    assert not s.fell and s.steps_completed == 12
    assert s.metrics.max_dcm_error_m < 0.01
    top = 1.5 if rise > 0 else 0.0
    assert s.last_state.feet["left"][2] == pytest.approx(top)


@pytest.mark.parametrize("recovery", ["next_step", "multi_step"])
def test_push_on_the_stairs_keeps_adjusted_footsteps_on_their_treads(recovery: str) -> None:
    config = stairs(0.15)
    config = config.replace(control={"recovery": recovery})
    s = Session(config, backend="lip")
    s.push((0.0, -100.0, 0.0), 0.2, start=3.2)  # 20 N·s lateral
    s.run(20.0)
    assert not s.fell
    spec = load_robot("talos").spec
    terrain = Terrain(stairs_boxes(0.15, 0.15, 0.30, 10, 1.2, 1.5))
    moved = [r for r in s.realised_steps() if np.linalg.norm(r.adjustment[:2]) > 1e-3]
    assert moved  # the push was large enough to adjust footsteps
    for r in s.realised_steps():
        corners = sole_corners(r.position, 0.0, spec.foot_length_m, spec.foot_width_m)
        heights = terrain.height_at(corners[:, :2] if corners.shape[1] > 2 else corners)
        assert np.ptp(heights) == 0.0 and r.position[2] == pytest.approx(heights[0])


def test_terrain_is_validated() -> None:
    with pytest.raises(ConfigError, match="terrain.stairs.rise"):
        loads_preset("[terrain.stairs]\nrise = 0.0")
    with pytest.raises(ConfigError, match="step_height"):
        loads_preset("[gait]\nstep_height = 0.05\n[terrain.stairs]\nrise = 0.1")


def test_a_recording_draws_the_stairs(tmp_path) -> None:
    """rerun: the stairs as solid boxes under world/terrain, each from the floor to its tread
    (tread i, 0.30 m deep, i·0.15 m high; the last one runs on as the 1.5 m landing)."""
    import rerun

    from dcmviz.record import record_session

    path = record_session(Session(stairs(0.15), backend="lip"), tmp_path / "stairs.rrd", 0.2)
    chunks = [
        c.to_record_batch()
        for c in rerun.chunk.RrdReader(str(path)).store().stream()
        if c.is_static and str(c.entity_path) == "/world/terrain"
    ]
    assert len(chunks) == 1
    centers = np.array(chunks[0].column("Boxes3D:centers").to_pylist()[0])
    half = np.array(chunks[0].column("Boxes3D:half_sizes").to_pylist()[0])
    tops = centers[:, 2] + half[:, 2]
    np.testing.assert_allclose(tops, 0.15 * np.arange(1, 11), atol=1e-6)
    np.testing.assert_allclose(centers[:, 2] - half[:, 2], 0.0, atol=1e-6)  # on the floor
    np.testing.assert_allclose(
        centers[:-1, 0] - half[:-1, 0], 0.15 + 0.30 * np.arange(9), atol=1e-6
    )
    assert centers[-1, 0] + half[-1, 0] == pytest.approx(0.15 + 0.30 * 10 + 1.5)


def test_the_dashboard_draws_the_terrain_of_the_preset_and_removes_it() -> None:
    """TerrainView: a box per tread at /terrain/<i> (floor to tread), none for a flat preset."""
    viser = pytest.importorskip("viser")
    from helpers import free_port

    from dcmviz.dashboard.terrain_view import TerrainView

    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        view = TerrainView(server.scene)
        view.show(stairs(0.15))
        assert [h.name for h in view.handles] == [f"/terrain/{i}" for i in range(10)]
        for i, h in enumerate(view.handles):
            assert h.position[2] + 0.5 * h.dimensions[2] == pytest.approx(0.15 * (i + 1))
            assert h.position[2] - 0.5 * h.dimensions[2] == pytest.approx(0.0)
        view.show(stairs(0.15).replace(terrain=None))
        assert view.handles == []
    finally:
        server.stop()
