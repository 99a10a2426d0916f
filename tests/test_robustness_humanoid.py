"""Issue 22's tug of war on the humanoids in MuJoCo (bench/robustness.py's scenario).

A lateral torso pull ramped over 6 s to a share of the robot's weight and held while it walks 12
steps (next_step, observer on), scanned over levels on both sides, never one pinned value.

Romeo (40.5 kg, 38 N m knees) fell at a 5 % pull while the walker lowered its CoM from b's
nominal height for the lean: its walking plan had already lowered the VRP by 7 mm for the
stride, the lean lowered it again, 12.8 mm in all, below the 1.2 cm of CoM height its legs
walk in, and the stance knee gave way.  Lowered from the plan's own height it survives 7.5 %
(10 % measured, see the test).
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import robustness_bench, survives_pull

from dcmviz.session import Session


@pytest.mark.slow
@pytest.mark.parametrize("side", [1.0, -1.0])
def test_romeo_walks_under_a_pull_up_to_7_5_percent_of_its_weight(side: float) -> None:
    """Survived at 2.5, 5 and 7.5 % (measured: 10 % survived on both sides, to +y only since
    SustainedLoad holds ramps, a knife-edge before; falls at 12.5 % and 15 % on both sides)."""
    for level in (2.5, 5.0, 7.5):
        assert survives_pull("romeo", level, side), level


@pytest.mark.slow
@pytest.mark.parametrize("side", [1.0, -1.0])
def test_romeos_pull_falls_are_its_actuators(tmp_path, side: float) -> None:
    """Romeo falls under a 15 % pull on either side with its URDF's torque limits (knees 38 N m
    for 40.5 kg, at their limit in 15-16 % of single support unpulled, and in ~60 % of the ticks
    from the pull to the fall); the same robot with every torque limit x1.5 (``[actuators]
    torque_scale``: the whole-body QP's bounds and MuJoCo's motors alike, every derived number
    as before) holds 15, 17.5 and 20 %: issue 22's 20 % on Romeo is its actuators' to give
    (measured with x1.5: 18, 19, 19.5, 20.5 and 21 % held on both sides too; first falls at
    22.5 % +y, 22 % -y)."""
    from dcmviz.robots.file import builtin_path

    text = builtin_path("romeo").read_text(encoding="utf-8")
    text = text.replace('name = "romeo"', 'name = "romeo_x1_5"')
    path = tmp_path / "romeo_x1_5.toml"
    path.write_text(text + "\n[actuators]\ntorque_scale = 1.5\n")
    assert not survives_pull("romeo", 15.0, side)
    for level in (15.0, 17.5, 20.0):
        assert survives_pull(str(path), level, side), level


@pytest.mark.slow
@pytest.mark.parametrize("side", [1.0, -1.0])
def test_talos_walks_under_a_pull_up_to_25_percent_of_its_weight(side: float) -> None:
    """Survived at 15, 20 and 25 % (the paper shows 15 %; measured: +y falls at 35 %, −y at
    30 %)."""
    for level in (15.0, 20.0, 25.0):
        assert survives_pull("talos", level, side), level


@pytest.mark.slow
@pytest.mark.parametrize("side", [1.0, -1.0])
def test_step_timing_holds_the_pulls_next_step_holds(side: float) -> None:
    """Talos with multi_step_timing at 25 and 30 % as with next_step (measured: both fall at
    35 %, crossover too; test_recovery checks both timing strategies' shift invariance).  It fell
    at 25 % while the re-timing compared the measured DCM with the soles themselves: leaned by
    the pull, ξ sat off them, and the timing QP stretched the phases as for a push."""
    for level in (25.0, 30.0):
        assert survives_pull("talos", level, side, "multi_step_timing"), level


@pytest.mark.slow
@pytest.mark.parametrize("recovery", ["next_step", "multi_step", "multi_step_timing"])
def test_the_g1s_multi_step_recovery_holds_the_pulls_next_step_holds(recovery: str) -> None:
    """The G1 pulled towards +y at 7.5, 10 and 12.5 % with each strategy (measured at c2ae811,
    both sides: next_step holds 20 %, multi_step 12.5 % (-y 15 % falls at the walk's end),
    multi_step_timing 15 %).  multi_step fell at 10 % (8.6 s) while its recovery QP credited
    the G1's CoP with 1 cm less than each side of its 6 cm wide sole (a third of it): the
    footsteps took the DCM error towards the pull where next_step's CoP held it.  The margin is
    now a share of the half width on a small sole (capacity_margin, 6 mm here).
    multi_step_timing fell at 10 % (+y) and 15 % (both sides, 4 s in) while the capacity's box
    in double support lagged the VRP's S-curve: a CoP shortfall in every double support, on
    which it re-timed the steps (test_recovery checks the box)."""
    for level in (7.5, 10.0, 12.5):
        assert survives_pull("g1", level, 1.0, recovery), level


def test_the_bench_names_the_joints_at_their_torque_limits_walking_unpushed() -> None:
    """bench/robustness.py's torque headroom against MuJoCo's own actuator forces, joint by
    joint (actuators looked up by name, not by order): Romeo's stance knees are at their
    38 N m limit in part of every single support even unpushed (why it falls at small pulls),
    Talos's joints never are."""
    import mujoco

    rb = robustness_bench()
    config = rb.walking_config("romeo")
    busy = {j["joint"]: j for j in rb.torque_headroom(config)}
    session = Session(config.model_copy(update={"pushes": []}), backend="mujoco")
    model, data = session.backend.model, session.backend.data
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) for i in range(model.nu)]
    limit = model.actuator_ctrlrange[:, 1]
    rows = []
    while session.t < rb.PUSH_DURATION_S and not session.fell:
        if session.step().swing_side is not None:
            rows.append(np.abs(data.actuator_force) / limit)
    at_limit = (np.array(rows) >= rb.AT_LIMIT).mean(axis=0)
    for i, name in enumerate(names):
        assert busy[name]["at_limit_share"] == pytest.approx(at_limit[i], abs=1e-9), name
    assert min(busy["LKneePitch"]["at_limit_share"], busy["RKneePitch"]["at_limit_share"]) > 0.05
    talos = rb.torque_headroom(rb.walking_config("talos"))
    assert max(j["peak_share"] for j in talos) < 0.8
