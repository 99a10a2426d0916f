"""Issue 22's push target against the paper's controller on the point mass (bench/robustness.py).

The paper's lateral pushes (±25 N × 1 s on Toro's 76 kg, scaled by the robot's mass) at four
start times over a gait cycle: the walker on the point mass with a robot's own numbers (mass,
CoM height, feet, reach) is the ceiling of what the humanoid under the same controller can do.
For the G1 (0.06 m wide soles) that ceiling lies between 1.5× and 2×: the target "2× at every
start" is above the paper's controller itself on that robot's numbers, not only above its
whole-body layer.  Talos's ceiling is above 2× at every start.

The paper pushes Toro at its CoM; bench/robustness.py pushes the humanoids at the torso, h above
the CoM.  Feet that counter the push's moment h F (no change of angular momentum) must move the
CoP h F/(m g) further, as if the point mass were pushed by F (z + h)/z (``lever_factor``; Talos
1.43).  With that load the point mass with Talos's numbers survives 1.5× at every start and
falls at 2× at three of four: the target "2× at every start" lies beyond the paper's controller
for a torso push unless the trunk takes the moment as angular momentum (issue 22, item 4).  The
humanoid in MuJoCo survives 2× at two starts.
"""

from __future__ import annotations

import pytest
from helpers import robustness_bench

from dcmviz.session import Session


def survived_starts(robot: str, scale: float, lever: bool = False) -> list[bool]:
    """Point mass, next_step, observer on: survived the push pair at each of four starts;
    ``lever``: the forces × (z + h)/z, as the torso push loads the CoP (bench --lever)."""
    rb = robustness_bench()
    factor = rb.lever_factor(robot) if lever else 1.0
    base = rb.walking_config(robot, sim="lip")
    mass = Session(base, backend="lip").mass
    cycle = 2.0 * (base.gait.t_ss + base.gait.t_ds)
    out = []
    for i in range(4):
        config = rb.push_config(base, mass, scale, rb.PUSH_FIRST_S + cycle * i / 4, factor)
        session = Session(config, backend="lip")
        out.append(not session.run(rb.PUSH_DURATION_S).fell)
    return out


@pytest.mark.parametrize("scale", [1.0, 1.25, 1.5])
def test_the_point_mass_with_g1_numbers_survives_up_to_1_5x_at_every_start(scale: float) -> None:
    assert all(survived_starts("g1", scale))


@pytest.mark.parametrize("scale", [2.0, 2.5, 3.0])
def test_the_point_mass_with_g1_numbers_falls_from_2x_at_some_start(scale: float) -> None:
    """Measured: 2× falls at 3 of 4 starts, 2.5× and 3× at all four (no holes)."""
    survived = survived_starts("g1", scale)
    assert not all(survived)
    assert sum(survived) <= 1


@pytest.mark.parametrize("scale", [1.5, 2.0])
def test_the_point_mass_with_talos_numbers_survives_2x_at_every_start(scale: float) -> None:
    assert all(survived_starts("talos", scale))


def test_the_lever_factor_is_the_torsos_height_over_the_com() -> None:
    rb = robustness_bench()
    from dcmviz.robots import load_robot

    talos = load_robot("talos")
    z, h = talos.spec.com_height_m, talos.push_lever_m("torso")
    assert 0.3 < h < 0.45 and 0.8 < z < 0.95
    assert rb.lever_factor("talos") == pytest.approx((z + h) / z, rel=1e-12)


def test_the_lever_factor_loads_the_com_as_the_torso_push_does() -> None:
    """A rigid body standing on its CoP edge: pushed by F at h above its CoM with the ground's
    moment about the CoM cancelling the push's (angular momentum constant), the lateral CoM
    acceleration from the Newton–Euler balance equals the point mass's with F (z + h)/z."""
    m, g, z, h, F, offset = 90.0, 9.81, 0.88, 0.38, 60.0, 0.05  # offset: CoM beyond the CoP
    # moments about the CoM (x part of r × force, in the y–z plane): the ground's force
    # (f, m g) at r = (−offset, −z) gives −offset m g + z f, the push (F, 0) at r = (0, h) gives
    # −h F; their sum is 0 (angular momentum constant)
    f = (h * F + offset * m * g) / z
    ydd = (f + F) / m  # Newton: lateral
    lip = (g / z) * offset + F * (z + h) / z / m  # point mass: (g/z)(c − p) + F'/m
    assert ydd == pytest.approx(lip, rel=1e-12)


@pytest.mark.parametrize("scale", [1.0, 1.25, 1.5])
def test_the_lever_loaded_point_mass_with_talos_numbers_survives_up_to_1_5x(scale: float) -> None:
    assert all(survived_starts("talos", scale, lever=True))


@pytest.mark.parametrize("scale", [2.0, 2.5, 3.0])
def test_the_lever_loaded_point_mass_with_talos_numbers_falls_from_2x(scale: float) -> None:
    """Measured: 1.75× falls at two starts, 2× at three, 2.5× at all four (no holes)."""
    assert sum(survived_starts("talos", scale, lever=True)) <= 1
