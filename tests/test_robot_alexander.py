"""``robots/alexander.toml``: IHMC's Alexander (lower body), a robot written from docs/robots.md
alone (issue 22, item 6).  Its mass against the URDF's own inertials, its standing soles flat
on the floor from Pinocchio's forward kinematics, and a MuJoCo walk of ``walk_forward``."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from dcmviz.robots import SIDES, example_robot_data_dir, load_robot

ROOT = Path(__file__).resolve().parents[1]
ALEXANDER = str(ROOT / "robots" / "alexander.toml")


def test_alexander_loads_with_the_urdfs_mass_and_stands_on_flat_soles() -> None:
    robot = load_robot(ALEXANDER)
    urdf = Path(example_robot_data_dir()) / "alexander_description" / "urdf"
    tree = ET.parse(urdf / "alexander_v1.lowerBodyOnly.urdf")
    mass = sum(float(m.get("value")) for m in tree.iter("mass"))
    soles = 2 * 1e-4  # the loader's sole links (dcmviz.robots.urdf: 1e-4 kg each)
    assert robot.spec.mass_kg == pytest.approx(mass + soles, rel=1e-12)
    model = robot.pin_model
    data = model.createData()
    pin.framesForwardKinematics(model, data, robot.q_nominal)
    soles = {s: data.oMf[robot.sole_frames[s]] for s in SIDES}
    for s in SIDES:
        np.testing.assert_allclose(soles[s].rotation[:, 2], [0.0, 0.0, 1.0], atol=1e-6)
        assert abs(soles[s].translation[2]) < 1e-6
    across = soles["left"].translation - soles["right"].translation
    assert across[1] == pytest.approx(robot.spec.foot_spacing_m, abs=1e-9) and across[1] > 0.2
    com = pin.centerOfMass(model, data, robot.q_nominal)
    assert com[2] == pytest.approx(robot.spec.com_height_m, abs=1e-6)


@pytest.mark.slow
def test_alexander_walks_the_default_preset_in_mujoco() -> None:
    """The default walk on the robot's own numbers (b from its standing CoM, its foot spacing):
    ten steps without falling, the DCM tracked within 5 cm (2.7 cm when measured)."""
    from dcmviz.run import load_config
    from dcmviz.session import Session

    spec = load_robot(ALEXANDER).spec
    config = load_config(
        str(ROOT / "presets" / "walk_forward.toml"),
        [f'robot.model="{ALEXANDER}"', f"dcm.b={spec.b_nominal_s!r}",
         f"gait.step_width={spec.foot_spacing_m!r}"],
    )  # fmt: skip
    session = Session(config, backend="mujoco")
    session.run(config.sim.duration, stop_on_fall=True)
    assert not session.fell and session.steps_completed == 10
    assert session.metrics.max_dcm_error_m < 0.05
