"""Terrain on the humanoid (issue 10): stairs built into the MuJoCo scene and walked by Talos.

Every number is checked against the stairs' own geometry (tread i stands i·rise high) and
MuJoCo's measured state, not against the planner's output.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from dcmviz.config import Config, load_preset, loads_preset
from dcmviz.gait.terrain import terrain_of
from dcmviz.robots import load_robot
from dcmviz.robots.geometry import sole_corners
from dcmviz.session import Session

RISE, RUN, COUNT, START = 0.15, 0.30, 2, 0.15
PRESETS = Path(__file__).resolve().parents[1] / "presets"

SHORT_STAIRS = """
[gait]
n_steps = 4
step_length = 0.30
t_ss = 0.9
t_ds = 0.3
t_start = 1.0
t_stop = 1.0
[dcm]
b = 0.278
[terrain.stairs]
start = 0.15
rise = {rise}
run = 0.30
count = 2
landing = 1.0
[sim]
backend = "mujoco"
"""


def short_stairs(rise: float) -> Config:
    return loads_preset(SHORT_STAIRS.format(rise=rise))


def tread_height(x: float, rise: float) -> float:
    """The ground under x, straight from the stairs' definition (not from dcmviz.gait.terrain)."""
    if rise > 0:  # treads i = 1..COUNT from START, the last one runs on as the landing
        i = int(np.floor((x - START) / RUN)) + 1
        return float(rise * min(max(i, 0), COUNT))
    top = -rise * COUNT  # a landing up to START, then COUNT - 1 treads down, then the floor
    i = int(np.floor((x - START) / RUN)) + 1
    return float(top + rise * min(max(i, 0), COUNT))


def test_the_scene_has_the_boxes_and_the_robot_stands_on_the_landing() -> None:
    config = short_stairs(-RISE)
    session = Session(config)
    backend = session.backend
    model, data = backend.model, backend.data
    terrain = terrain_of(config.terrain)
    names = [model.geom(i).name for i in range(model.ngeom)]
    boxes = [model.geom(n) for n in names if n.startswith("terrain_")]
    assert len(boxes) == len(terrain.boxes) == COUNT
    floor = model.geom("floor")
    for geom, box in zip(boxes, terrain.boxes, strict=True):
        assert geom.type[0] == mujoco.mjtGeom.mjGEOM_BOX
        top = geom.pos[2] + geom.size[2]
        assert top == pytest.approx(box.top) and geom.pos[2] - geom.size[2] == pytest.approx(0)
        np.testing.assert_allclose(geom.friction, floor.friction)
        assert (geom.contype[0], geom.conaffinity[0]) == (1, 1)
    # standing still on the landing (0.30 m): the soles rest on it, and it carries the weight
    for _ in range(250):
        session.step()
    for side in ("left", "right"):
        site = data.site_xpos[model.site(f"{side}_sole").id]
        assert site[2] == pytest.approx(RISE * COUNT, abs=2e-3)
    assert session.last_state.in_contact == {"left": True, "right": True}
    weight = session.mass * 9.81
    assert sum(backend.contact_forces.values()) == pytest.approx(weight, rel=0.05)
    assert not session.fell


@pytest.mark.slow
@pytest.mark.parametrize("rise", [RISE, -RISE])
def test_talos_walks_a_short_staircase(rise: float) -> None:
    """Two 0.15 m steps up (down) onto the landing (floor): no fall, every sole lands flat
    on one tread at its height (measured by MuJoCo), horizontal DCM error below 3 cm."""
    session = Session(short_stairs(rise))
    spec = load_robot("talos").spec
    landed: list[tuple[str, np.ndarray, float]] = []
    seen = [0]

    def on_tick(tick) -> None:
        if tick.steps_completed > seen[0]:  # a touchdown committed this tick
            seen[0] = tick.steps_completed
            side = tick.realised_steps[-1].side
            landed.append((side, tick.state.feet[side].copy(), tick.state.feet_yaw[side]))

    session.subscribe(on_tick)
    session.run(7.0)
    assert not session.fell
    assert session.steps_completed == 4
    error = session.history()["xi"] - session.history()["xi_ref"]
    assert np.abs(np.linalg.norm(error[:, :2], axis=1)).max() < 0.03
    expected_x = [0.30, 0.60, 0.90, 0.90]
    for (side, foot, yaw), x in zip(landed, expected_x, strict=True):
        assert foot[0] == pytest.approx(x, abs=0.03)
        assert foot[2] == pytest.approx(tread_height(foot[0], rise), abs=5e-3)
        corners = sole_corners(foot, yaw, spec.foot_length_m, spec.foot_width_m)
        under = [tread_height(c[0], rise) for c in corners]
        assert max(under) == min(under), f"{side} sole at {foot} straddles an edge"
    # both feet end on the top landing (the floor) at its height
    for side in ("left", "right"):
        assert session.last_state.feet[side][2] == pytest.approx(tread_height(0.9, rise), abs=5e-3)


@pytest.mark.slow
def test_g1_climbs_a_short_staircase_of_8_cm() -> None:
    """The G1 (presets/stairs_g1.toml, shortened to two treads): its soles land on treads at
    0.08 and 0.16 m, horizontal DCM error below 3 cm, no fall."""
    config = load_preset(PRESETS / "stairs_g1.toml")
    config = config.replace(
        gait={"n_steps": 4},
        terrain={"stairs": {**config.terrain.stairs.model_dump(), "count": 2}},
    )
    session = Session(config)
    session.run(1.0 + 4 * 0.9 + 1.0)
    assert not session.fell and session.steps_completed == 4
    error = session.history()["xi"] - session.history()["xi_ref"]
    assert np.linalg.norm(error[:, :2], axis=1).max() < 0.03
    for side in ("left", "right"):  # both on the landing (the second tread), 0.16 m high
        assert session.last_state.feet[side][0] == pytest.approx(0.75, abs=0.03)
        assert session.last_state.feet[side][2] == pytest.approx(0.16, abs=5e-3)


@pytest.mark.slow
def test_a_lateral_push_of_20_newton_seconds_on_the_stairs_is_survived() -> None:
    """presets/stairs_up.toml, 100 N for 0.2 s to the left during the third step (on the
    0.15 m stairs): the observer sees the push, the swinging foot lands further left, still
    flat on its tread at its height, and the DCM error returns below 3 cm (horizontal)."""
    config = load_preset(PRESETS / "stairs_up.toml")
    session = Session(config)
    session.push((0.0, 100.0, 0.0), 0.2, start=3.8)
    session.run(7.0)
    assert not session.fell
    h = session.history()
    during = (h["t"] >= 3.8) & (h["t"] < 4.0)
    assert h["f_hat"][during, 1].max() > 30.0  # the observer's estimate of the 100 N push
    spec = load_robot("talos").spec
    third = session.realised_steps()[2]
    assert third.adjustment[1] > 0.05  # stepped left to catch the push
    assert third.position[0] == pytest.approx(0.90, abs=0.03)  # on its tread (0.75–1.05 m)
    corners = sole_corners(third.position, 0.0, spec.foot_length_m, spec.foot_width_m)
    assert {int(np.floor((c[0] - START) / RUN)) + 1 for c in corners} == {3}  # all on tread 3
    error = h["xi"] - h["xi_ref"]
    assert np.linalg.norm(error[-50:, :2], axis=1).max() < 0.03
