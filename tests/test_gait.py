"""Footstep plans, VRP waypoints, contact schedule and swing paths."""

import itertools
import math

import numpy as np
import pytest

from dcmviz import GRAVITY
from dcmviz.config import Config, config_from_dict
from dcmviz.gait import (
    OTHER,
    Footstep,
    SwingTrajectory,
    build_plan,
    horizon_steps,
    plan_footsteps,
    plan_from_config,
    timing_of,
)
from dcmviz.robots import clamp_to_reach, load_robot, reach_problem


def test_waypoints_sit_dz_above_the_feet_and_d1_d2_d3_hold():
    config = Config()
    plan = plan_from_config(config)
    dz = GRAVITY * 0.3**2
    feet = plan.start_feet
    mid0 = 0.5 * (feet["left"].position + feet["right"].position) + [0, 0, dz]
    mid_end = 0.5 * (plan.steps[-1].position + plan.steps[-2].position) + [0, 0, dz]
    wp = plan.waypoints
    np.testing.assert_allclose(wp[0], mid0, atol=1e-12)  # D1
    np.testing.assert_allclose(plan.preview.xi_ref_0[0], mid0, atol=1e-9)  # D2
    np.testing.assert_allclose(wp[-1], mid_end, atol=1e-12)  # D3
    np.testing.assert_allclose(plan.preview.dcm(plan.duration), mid_end, atol=1e-12)  # (17)
    # every single-support phase keeps the VRP on the stance sole, Δz_vrp above it
    for p, kind in enumerate(plan.phase_kind):
        if kind == "ss":
            stance = plan.stance_for(plan.phase_step[p])
            np.testing.assert_allclose(wp[p], stance.position + [0, 0, dz], atol=1e-12)
            np.testing.assert_allclose(wp[p + 1], stance.position + [0, 0, dz], atol=1e-12)


def test_durations_and_phase_sequence():
    g = Config().gait
    plan = plan_from_config(Config())
    n = g.n_steps
    assert plan.phase_kind == ("start_a", "start_b") + ("ss", "ds") * (n - 1) + ("ss", "stop")
    expected = g.t_start + n * g.t_ss + (n - 1) * g.t_ds + g.t_stop
    assert plan.duration == pytest.approx(expected, abs=1e-12)


def test_generated_steps_alternate_turn_and_climb():
    c = config_from_dict(
        {"gait": {"n_steps": 6, "turn": 0.2, "step_height": 0.05, "step_length": 0.2}}
    )
    _, steps = plan_footsteps(c.gait)
    assert [s.side for s in steps] == ["left", "right"] * 3
    assert steps[4].yaw == pytest.approx(5 * 0.2)
    assert steps[4].position[2] == pytest.approx(5 * 0.05)
    assert steps[5].position[2] == pytest.approx(steps[4].position[2])  # closing step
    # feet stay step_width apart across the heading
    a, b = steps[4], steps[5]
    lateral = (b.position - a.position)[:2] @ np.array([-math.sin(a.yaw), math.cos(a.yaw)])
    assert abs(lateral) == pytest.approx(c.gait.step_width, abs=1e-9)
    # stairs: the VRP rises with the feet (3-D waypoints)
    plan = plan_from_config(c)
    assert plan.waypoints[-1][2] == pytest.approx(steps[-1].position[2] + GRAVITY * 0.09)


def test_contact_schedule():
    plan = plan_from_config(Config())
    g = Config().gait
    t_lift = g.t_start + 0.1
    c = plan.contact(t_lift)
    assert c.kind == "ss" and c.swing_side == "left" and c.support == {"left": False, "right": True}
    c = plan.contact(g.t_start + g.t_ss + 0.05)
    assert c.kind == "ds" and c.support == {"left": True, "right": True}
    c = plan.contact(g.t_start + g.t_ss + g.t_ds + 0.05)
    assert c.swing_side == "right"
    assert plan.contact(plan.duration + 1.0).kind == "stand"
    assert plan.swing_window(0) == pytest.approx((g.t_start, g.t_start + g.t_ss))


def test_with_step_moves_only_that_footsteps_waypoints():
    plan = plan_from_config(Config())
    delta = np.array([0.03, -0.05, 0.0])
    moved = plan.with_step(3, plan.steps[3].position + delta)
    changed = np.where(np.any(moved.waypoints != plan.waypoints, axis=1))[0]
    assert set(changed) == set(plan.step_waypoint_weights[3])
    np.testing.assert_allclose(
        moved.waypoints[changed] - plan.waypoints[changed],
        np.tile(delta, (len(changed), 1)),
        atol=1e-12,
    )
    # the DCM reference before the first affected phase moves, but smoothly (eq. 34: linear)
    t = plan.phase_start(plan.first_affected_phase(3)) - 0.3
    expected = plan.preview.dcm(t) + (plan.preview.dcm_weights(t) @ plan.selection(3)) * delta
    np.testing.assert_allclose(moved.preview.dcm(t), expected, atol=1e-12)


@pytest.mark.parametrize("order", [0, 3, 5])
def test_with_step_equals_the_plan_rebuilt_with_that_footstep_moved(order):
    """Step adjustment moves footstep k's waypoints by S_adj (eq. 29): the horizontal waypoints
    of plan.with_step(k) are those of the plan built afresh with footstep k moved, for every
    footstep — the penultimate one included, whose stance foot carries half of the final
    standing point (before, an adjusted penultimate footstep left the final standing DCM where
    the nominal feet would have been).  Not compared: the start's continuity waypoint w2 (D2,
    solved from the whole plan when it is built; a walk under way keeps it) and heights (a
    walk keeps its planned VRP heights)."""
    spec = load_robot("talos").spec
    plan = plan_from_config(Config().replace(dcm={"order": order}), spec=spec)
    delta = np.array([0.03, -0.05, 0.0])
    keep = np.r_[0, 2 : len(plan.preview.waypoints)]  # all but w2
    for k in range(len(plan.steps)):
        moved = plan.with_step(k, plan.steps[k].position + delta)
        steps = list(plan.steps)
        steps[k] = steps[k].moved(steps[k].position + delta)
        rebuilt = build_plan(
            plan.start_feet, tuple(steps), plan.timing, plan.b, plan.order, t0=plan.t0, spec=spec
        )
        np.testing.assert_allclose(
            moved.preview.waypoints[keep, :2],
            rebuilt.preview.waypoints[keep, :2],
            atol=1e-12,
            err_msg=f"footstep {k}",
        )


def test_continuous_horizon_and_transfer_plan():
    g = config_from_dict({"gait": {"mode": "continuous"}}).gait
    feet = {
        s: Footstep(s, np.array([0.0, y, 0.0])) for s, y in (("left", 0.085), ("right", -0.085))
    }
    steps = horizon_steps(g, feet, "left", 4)
    assert [s.side for s in steps] == ["left", "right", "left", "right"]
    np.testing.assert_allclose([s.position[0] for s in steps], [0.2, 0.4, 0.6, 0.8], atol=1e-12)
    plan = build_plan(feet, steps, timing_of(g), 0.3, 5, start="transfer", landed="left", t0=5.0)
    assert plan.phase_kind[0] == "ds" and plan.t0 == 5.0
    # begins with the VRP on the foot the weight leaves
    np.testing.assert_allclose(plan.preview.vrp(0.0)[:2], feet["right"].position[:2])


def _fd(fun, t, h=1e-5):
    return (fun(t + h) - fun(t - h)) / (2 * h)


def test_swing_path_boundary_conditions_and_retarget_is_c2():
    lift = Footstep("left", np.array([0.0, 0.085, 0.0]))
    touch = Footstep("left", np.array([0.4, 0.085, 0.05]), 0.2)
    swing = SwingTrajectory.between(1.0, 1.7, lift, touch)
    p, v, a, yaw, _ = swing.sample(1.0)
    np.testing.assert_allclose(p, lift.position, atol=1e-12)
    np.testing.assert_allclose(v, 0, atol=1e-12)
    p, v, a, yaw, _ = swing.sample(1.7)
    np.testing.assert_allclose(p, touch.position, atol=1e-12)
    assert yaw == pytest.approx(0.2)
    assert swing.sample(1.35)[0][2] > 0.05 + 0.04  # clears the higher end by the apex height
    # velocity / acceleration are the derivatives of position (finite differences)
    for t in (1.1, 1.3, 1.55):
        np.testing.assert_allclose(
            swing.sample(t)[1], _fd(lambda s: swing.sample(s)[0], t), atol=1e-5
        )
        np.testing.assert_allclose(
            swing.sample(t)[2], _fd(lambda s: swing.sample(s)[1], t), atol=1e-3
        )
    # re-targeting mid-swing keeps position, velocity and acceleration continuous
    t_r = 1.3
    new = swing.retarget(t_r, np.array([0.45, 0.2, 0.05]))
    for i in range(3):
        np.testing.assert_allclose(new.sample(t_r)[i], swing.sample(t_r)[i], atol=1e-9)
    np.testing.assert_allclose(new.sample(1.7)[0][:2], [0.45, 0.2], atol=1e-12)
    np.testing.assert_allclose(new.sample(1.7)[1], 0, atol=1e-9)
    # frozen near touchdown
    assert swing.retarget(1.65, np.array([1.0, 1.0, 0.0])) is swing


# -- generated footsteps: straight walking unchanged, turning inside the robot's reach ----------


def _stance_frame(stance: Footstep, step: Footstep) -> tuple[float, float, float]:
    """(Δx, lateral toward the step's side, Δyaw) of ``step`` in ``stance``'s frame."""
    d = step.position - stance.position
    c, s = math.cos(stance.yaw), math.sin(stance.yaw)
    sign = 1.0 if step.side == "left" else -1.0
    return c * d[0] + s * d[1], sign * (-s * d[0] + c * d[1]), step.yaw - stance.yaw


def _walk(steps, feet):
    """Each step with the foot it steps from."""
    feet = dict(feet)
    for step in steps:
        yield feet[OTHER[step.side]], step
        feet[step.side] = step


def _soles_intersect(a: Footstep, b: Footstep, length: float, width: float) -> bool:
    """Brute force: a 2 mm grid of sole b tested point by point against rectangle a."""
    u, v = np.meshgrid(np.linspace(-0.5, 0.5, 106), np.linspace(-0.5, 0.5, 66))
    local = np.stack([u.ravel() * length, v.ravel() * width], axis=1)
    c, s = math.cos(b.yaw), math.sin(b.yaw)
    world = b.position[:2] + local @ np.array([[c, s], [-s, c]])
    d = world - a.position[:2]
    ca, sa = math.cos(a.yaw), math.sin(a.yaw)
    x, y = d @ np.array([ca, sa]), d @ np.array([-sa, ca])
    return bool(np.any((np.abs(x) < 0.5 * length) & (np.abs(y) < 0.5 * width)))


@pytest.mark.parametrize("first", ["left", "right"])
def test_straight_walking_is_bit_identical(first):
    """Sole centres at (Σ L, ±w/2, Σ Δz), summed one step at a time as before turning changed."""
    for L, w, h in ((0.2, 0.17, 0.0), (-0.13, 0.23, 0.05), (0.37, 0.19, -0.03)):
        g = config_from_dict(
            {
                "gait": {
                    "n_steps": 9,
                    "step_length": L,
                    "step_width": w,
                    "step_height": h,
                    "first_swing": first,
                }
            }
        ).gait
        feet, steps = plan_footsteps(g)
        horizon = horizon_steps(g, feet, first, 9)
        x = z = 0.0
        for k in range(9):
            if k < 8:  # the closing step (k = 8) lands beside footstep 8
                x, z = x + L, z + h
            side = first if k % 2 == 0 else OTHER[first]
            y = (0.5 * w) if side == "left" else -(0.5 * w)
            assert steps[k].side == side and steps[k].yaw == 0.0
            assert steps[k].position.tolist() == [x, y, z]
        x = z = 0.0
        for k, step in enumerate(horizon):
            x, z = x + L, z + h
            assert step.position.tolist() == [x, steps[k].position[1], z] and step.yaw == 0.0


@pytest.mark.parametrize(
    ("robot", "lengths", "widths"),
    [
        ("talos", (-0.15, 0.0, 0.2, 0.4), (0.16, 0.17, 0.23, 0.30)),
        ("g1", (-0.10, 0.0, 0.12, 0.25), (0.20, 0.24, 0.30)),
    ],
)
def test_turning_steps_stay_inside_reach_in_both_modes(robot, lengths, widths):
    """Up to ±0.3 rad per step: every step ≥ the robot's minimum width from its stance foot (in the
    stance foot's frame), inside its reach, soles apart; clamp_to_reach moves none of them."""
    spec = load_robot(robot).spec
    b = spec.b_nominal_s
    for turn, L, w in itertools.product((-0.3, -0.2, -0.05, 0.05, 0.2, 0.3), lengths, widths):
        gait = {"n_steps": 7, "step_length": L, "step_width": w, "turn": turn}
        g = config_from_dict({"robot": {"model": robot}, "gait": gait, "dcm": {"b": b}}).gait
        feet, steps = plan_footsteps(g)
        horizon = horizon_steps(g, feet, g.first_swing, 7)
        for walked, closing in ((steps, True), (horizon, False)):
            for k, (stance, step) in enumerate(_walk(walked, feet)):
                dx, lateral, dyaw = _stance_frame(stance, step)
                last = closing and k == len(walked) - 1
                assert lateral == pytest.approx(w, abs=1e-12)
                assert dyaw == pytest.approx(0.0 if last else turn, abs=1e-12)
                assert dx == pytest.approx(0.0 if last else L + w * math.tan(abs(turn) / 2))
                assert reach_problem(spec, stance, step) == "", (turn, L, w, k)
                assert not _soles_intersect(stance, step, spec.foot_length_m, spec.foot_width_m)
                clamped = clamp_to_reach(spec, stance, step, step.position, 0.3)
                np.testing.assert_allclose(clamped, step.position, atol=1e-12)


@pytest.mark.parametrize("turn", [0.2, 0.3, -0.3, 0.5])
def test_turning_in_place_pivots_about_the_inner_foot(turn):
    """step_length 0: after its first step the inner foot only turns; the outer foot swings
    around it at w / cos(turn / 2) (both feet at (w tan(|turn|/2), ±w) in each other's frame)."""
    w = 0.17
    g = config_from_dict({"gait": {"n_steps": 9, "step_length": 0.0, "turn": turn}}).gait
    feet, steps = plan_footsteps(g)
    steps = steps[:-1]  # the closing step lands beside the last one
    inner = "left" if turn > 0 else "right"
    inner_steps = [s for s in steps if s.side == inner]
    for s in inner_steps[1:]:
        np.testing.assert_allclose(s.position, inner_steps[0].position, atol=1e-12)
    assert [s.yaw for s in inner_steps] == pytest.approx(
        [(k + 1) * turn for k, s in enumerate(steps) if s.side == inner]
    )
    for stance, step in _walk(steps, feet):
        if step.side != inner and stance.side == inner:
            d = np.linalg.norm(step.position[:2] - stance.position[:2])
            assert d == pytest.approx(w / math.cos(turn / 2), abs=1e-12)


def test_the_drawn_swing_path_is_the_sampled_one_still_to_go():
    """SwingTrajectory.path (all points at once, drawn by the dashboard) equals sample(t) at
    PATH_SAMPLES times evenly from the current segment's start to touchdown: a flat step, a
    step over stairs, and a crossing step round the stance foot re-targeted mid-swing (its
    detour on)."""
    from dcmviz.gait.swing import PATH_SAMPLES
    from dcmviz.gait.terrain import Terrain, stairs_boxes

    sole = (0.21, 0.13)
    flat = SwingTrajectory.between(
        1.0, 1.7, Footstep("left", np.array([0.0, 0.085, 0.0])),
        Footstep("left", np.array([0.4, 0.085, 0.05]), 0.2),
    )  # fmt: skip
    stairs = SwingTrajectory.between(
        0.0, 0.9, Footstep("left", np.array([0.3, 0.085, 0.15])),
        Footstep("left", np.array([0.9, 0.085, 0.45])),
        terrain=Terrain(stairs_boxes(0.15, 0.15, 0.30, 10, 1.2, 1.5)), sole=sole,
    )  # fmt: skip
    stance = Footstep("right", np.array([0.2, -0.085, 0.0]))
    crossing = SwingTrajectory.between(
        2.0, 2.7, Footstep("left", np.array([0.0, 0.085, 0.0])),
        Footstep("left", np.array([0.25, 0.05, 0.0])), sole=sole, stance=stance,
    ).retarget(2.2, np.array([0.4, -0.25, 0.0]))  # fmt: skip
    assert crossing.detour != (0.0, 0.0)  # it goes round the stance foot
    for swing in (flat, stairs, crossing):
        times = np.linspace(swing.t_seg, swing.t_touch, PATH_SAMPLES)
        expected = np.array([swing.sample(t)[0] for t in times])
        np.testing.assert_allclose(swing.path, expected, atol=1e-12)
        np.testing.assert_allclose(swing.path[-1], swing.target, atol=1e-12)
        assert not swing.path.flags.writeable
