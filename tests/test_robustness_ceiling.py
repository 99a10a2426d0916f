"""Issue 22's push target against the paper's controller on the point mass (bench/robustness.py).

The paper's lateral pushes (±25 N × 1 s on Toro's 76 kg, scaled by the robot's mass) at four
start times over a gait cycle: the walker on the point mass with a robot's own numbers (mass,
CoM height, feet, reach) is the ceiling of what the humanoid under the same controller can do.
For the G1 (0.06 m wide soles) that ceiling lies between 1.5× and 2×: the target "2× at every
start" is above the paper's controller itself on that robot's numbers, not only above its
whole-body layer.  Talos's ceiling is above 2× at every start.
"""

from __future__ import annotations

import pytest
from helpers import robustness_bench

from dcmviz.session import Session


def survived_starts(robot: str, scale: float) -> list[bool]:
    """Point mass, next_step, observer on: survived the push pair at each of four starts."""
    rb = robustness_bench()
    base = rb.walking_config(robot, sim="lip")
    mass = Session(base, backend="lip").mass
    cycle = 2.0 * (base.gait.t_ss + base.gait.t_ds)
    out = []
    for i in range(4):
        config = rb.push_config(base, mass, scale, rb.PUSH_FIRST_S + cycle * i / 4)
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
