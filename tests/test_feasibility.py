"""Feasibility of a plan: each limit broken on purpose is named; the geometry against brute force."""

from __future__ import annotations

import itertools
import json
import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from dcmviz import GRAVITY
from dcmviz.config import Config, config_from_dict, load_preset
from dcmviz.gait import Footstep, build_plan, plan_footsteps, plan_from_config, timing_of
from dcmviz.gait.feasibility import SUPPORT_MARGIN_M, check_plan
from dcmviz.robots import load_robot
from dcmviz.robots.geometry import hull_depth, rectangle_gap, soles_corners
from dcmviz.run import main

PRESETS = sorted(Path(__file__).parents[1].joinpath("presets").glob("*.toml"))
TALOS = load_robot("talos").spec


# -- independent geometry: point in rectangle, point in triangle (Carathéodory) -----------------


def _in_sole(point: np.ndarray, foot: Footstep, margin: float, length: float, width: float) -> bool:
    """The point is ≥ margin inside the sole rectangle (its own frame)."""
    d = point[:2] - foot.position[:2]
    c, s = math.cos(foot.yaw), math.sin(foot.yaw)
    x, y = c * d[0] + s * d[1], -s * d[0] + c * d[1]
    return abs(x) <= 0.5 * length - margin and abs(y) <= 0.5 * width - margin


def _in_hull(point: np.ndarray, vertices: np.ndarray) -> bool:
    """Carathéodory: a point of the plane is in the hull of a set iff in a triangle of three of it."""
    p = np.asarray(point, dtype=float)
    for a, b, c in itertools.combinations(vertices, 3):
        d1 = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
        d2 = (c[0] - b[0]) * (p[1] - b[1]) - (c[1] - b[1]) * (p[0] - b[0])
        d3 = (a[0] - c[0]) * (p[1] - c[1]) - (a[1] - c[1]) * (p[0] - c[0])
        neg = d1 < -1e-15 or d2 < -1e-15 or d3 < -1e-15
        pos = d1 > 1e-15 or d2 > 1e-15 or d3 > 1e-15
        if not (neg and pos):
            return True
    return False


def _in_hull_with_margin(point: np.ndarray, vertices: np.ndarray, margin: float) -> bool:
    """The disc of radius ``margin`` about the point lies in the hull (64 points of its circle)."""
    angles = np.linspace(0.0, 2 * math.pi, 64, endpoint=False)
    ring = point[:2] + margin * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    return all(_in_hull(q, vertices) for q in ring)


def _feet_at(plan, t: float) -> dict[str, Footstep]:
    """Where each foot stands at plan time t (steps land at the end of their swing)."""
    feet = dict(plan.start_feet)
    for k, step in enumerate(plan.steps):
        if plan.swing_window(k)[1] <= t + 1e-9:
            feet[step.side] = step
    return feet


def _support_ok(plan, i: int, spec) -> bool:
    """Waypoint i (boundary between phases i − 1 and i) ≥ margin inside the feet bearing weight
    on both sides of its instant, from the contact schedule."""
    t_i = plan.t0 + float(np.concatenate([[0.0], np.cumsum(plan.durations)])[i])
    sides = {"left", "right"}
    for t in (t_i - 1e-6, t_i + 1e-6):
        if plan.t0 <= t < plan.t_end:
            sides &= {s for s, down in plan.contact(t).support.items() if down}
    feet = _feet_at(plan, t_i)
    p = plan.waypoints[i]
    L, W = spec.foot_length_m, spec.foot_width_m
    if len(sides) == 1:
        return _in_sole(p, feet[sides.pop()], SUPPORT_MARGIN_M, L, W)
    corners = np.vstack([soles_corners(f.position[None], [f.yaw], L, W)[0] for f in feet.values()])
    return _in_hull_with_margin(p, corners, SUPPORT_MARGIN_M)


def _soles_intersect(a: Footstep, b: Footstep, length: float, width: float) -> bool:
    """A 2 mm grid of sole b tested point by point against rectangle a (in a's frame)."""
    u, v = np.meshgrid(np.linspace(-0.5, 0.5, 106), np.linspace(-0.5, 0.5, 66))
    pts = np.stack([u.ravel() * length, v.ravel() * width], axis=1)
    c, s = math.cos(b.yaw), math.sin(b.yaw)
    d = b.position[:2] + pts @ np.array([[c, s], [-s, c]]) - a.position[:2]
    ca, sa = math.cos(a.yaw), math.sin(a.yaw)
    x, y = d @ np.array([ca, sa]), d @ np.array([-sa, ca])
    return bool(np.any((np.abs(x) < 0.5 * length) & (np.abs(y) < 0.5 * width)))


# -- geometry helpers ----------------------------------------------------------------------------


def test_hull_depth_against_triangles_and_rectangles():
    rng = np.random.default_rng(3)
    L, W = TALOS.foot_length_m, TALOS.foot_width_m
    checked = 0
    for _ in range(60):
        feet = [
            Footstep("left", np.array([*rng.uniform(-0.2, 0.2, 2), 0.0]), rng.uniform(-0.6, 0.6))
            for _ in range(2)
        ]
        single = rng.random() < 0.4
        if single:
            feet[1] = feet[0]
        corners = soles_corners(
            np.array([f.position for f in feet]), [f.yaw for f in feet], L, W
        ).reshape(8, 2)
        points = corners.mean(0) + rng.uniform(-0.25, 0.25, (12, 2))
        depth = hull_depth(points, np.broadcast_to(corners, (12, 8, 2)))
        for p, d in zip(points, depth, strict=True):
            if abs(d - SUPPORT_MARGIN_M) < 2e-4:  # too close to the margin to tell by sampling
                continue
            inside = d >= SUPPORT_MARGIN_M
            if single:
                assert inside == _in_sole(p, feet[0], SUPPORT_MARGIN_M, L, W)
            assert inside == _in_hull_with_margin(p, corners, SUPPORT_MARGIN_M)
            assert (d >= 0) == _in_hull(p, corners) or abs(d) < 1e-9
            checked += 1
    assert checked > 600


def test_rectangle_gap_against_brute_force():
    rng = np.random.default_rng(5)
    L, W = TALOS.foot_length_m, TALOS.foot_width_m
    a = [Footstep("left", np.zeros(3), rng.uniform(-1, 1)) for _ in range(150)]
    b = [
        Footstep("right", np.array([*rng.uniform(-0.25, 0.25, 2), 0.0]), rng.uniform(-1, 1))
        for _ in range(150)
    ]
    gap = rectangle_gap(
        soles_corners(np.array([f.position for f in a]), [f.yaw for f in a], L, W),
        soles_corners(np.array([f.position for f in b]), [f.yaw for f in b], L, W),
    )
    for fa, fb, g in zip(a, b, gap, strict=True):
        if abs(g) > 3e-3:  # beyond the brute force's grid
            assert (g <= 0) == _soles_intersect(fa, fb, L, W), g


# -- plans -------------------------------------------------------------------------------------


@pytest.mark.parametrize("path", PRESETS, ids=lambda p: p.stem)
def test_shipped_presets_are_feasible(path):
    config = load_preset(path)
    plan = plan_from_config(config)
    warnings = check_plan(plan, load_robot(config.robot.model).spec, config)
    if any(step.position[2] != 0.0 for step in plan.steps):  # stairs: the legs reach down half
        # a rise, the CoM walks lower
        warnings = [w for w in warnings if "walk lowers the CoM" not in w.message]
    assert warnings == []
    assert all(
        _support_ok(plan, i, load_robot(config.robot.model).spec)
        for i in range(len(plan.waypoints))
    )


def test_d2_outside_the_support_polygon_names_t_start():
    config = config_from_dict({"gait": {"t_start": 0.2}})
    plan = plan_from_config(config)
    warnings = check_plan(plan, TALOS, config)
    assert [(w.setting, w.waypoint, w.step) for w in warnings] == [("gait.t_start", 1, None)]
    message = str(warnings[0])
    for word in ("VRP waypoint 2", "D2", "outside", "0.010 m", "gait.t_start", "dcm.b"):
        assert word in message, message
    # the numbers: w2_y ≈ 0.19 m against a polygon |y| ≤ 0.085 + 0.065 m
    assert plan.waypoints[1, 1] == pytest.approx(0.19, abs=0.005)
    assert not _support_ok(plan, 1, TALOS)


def test_waypoints_flagged_exactly_where_the_schedule_says():
    """Single-support waypoints moved off the stance sole, one a little, one by more."""
    config = Config()
    plan = plan_from_config(config)
    wp = plan.waypoints.copy()
    ss = [p for p, kind in enumerate(plan.phase_kind) if kind == "ss"]
    wp[ss[2], 1] += 0.06  # 5 mm less than the 1 cm margin
    wp[ss[4] + 1, 0] += 0.2  # end of single support: beyond the toes
    wp[ss[6], 1] += 0.05  # still 5 mm inside the margin
    moved = replace(plan, preview=plan.preview.with_waypoints(wp))
    warnings = check_plan(moved, TALOS, config)
    flagged = [w.waypoint for w in warnings]
    expected = [i for i in range(len(wp)) if not _support_ok(moved, i, TALOS)]
    assert flagged == expected == [ss[2], ss[4] + 1]
    assert "single support" in str(warnings[0]) and "only 0.005 m inside" in str(warnings[0])
    assert warnings[1].step == plan.phase_step[ss[4]]
    assert f"footstep {warnings[1].step + 1}" in str(warnings[1])


def _plan_with(steps, gait_config=None, b=0.3):
    config = gait_config or Config()
    feet, _ = plan_footsteps(config.gait)
    return build_plan(feet, tuple(steps), timing_of(config.gait), b, 5), config


def test_out_of_reach_and_too_narrow_steps_name_the_footstep_and_limit():
    _, steps = plan_footsteps(Config().gait)
    steps = list(steps)
    steps[2] = steps[2].moved(steps[2].position + [0.3, 0.0, 0.0])  # 0.5 m from footstep 2
    steps[5] = steps[5].moved(steps[5].position + [0.0, 0.05, 0.0])  # 0.12 m beside footstep 5
    plan, config = _plan_with(steps)
    # (the 0.5 m stride also lowers the CoM: that warning names dcm.b, tested in test_height.py)
    warnings = [
        w
        for w in check_plan(plan, TALOS, config)
        if "swings" not in str(w) and w.setting != "dcm.b"
    ]
    # footstep 6 is too close and its sole overlaps, and so is footstep 7 next to it
    reach, narrow, overlap = warnings[:3]
    assert [w.step for w in warnings[3:]] == [6, 6]
    assert (reach.step, narrow.step, overlap.step) == (2, 5, 5)
    assert "footstep 3" in str(reach) and "0.45 m" in str(reach)
    assert reach.setting == "gait.step_length"
    assert "footstep 6" in str(narrow) and "0.120 m" in str(narrow) and "0.14 m" in str(narrow)
    assert narrow.setting == "gait.step_width"
    assert "footstep 6" in str(overlap) and "overlaps the left sole by 0.010 m" in str(overlap)
    # the same footsteps given in the preset are named by their index there
    explicit = config_from_dict(
        {
            "gait": {
                "footsteps": [
                    {"side": s.side, "position": s.position.tolist(), "yaw": s.yaw}
                    for s in plan_footsteps(Config().gait)[1]
                ]
            }
        }
    )
    named = {w.step: w.setting for w in check_plan(plan, TALOS, explicit)}
    assert named[2] == "gait.footsteps[2]" and named[5] == "gait.footsteps[5]"


def test_overlapping_soles_when_turning_in_place_narrow():
    """Turning in place at Talos's minimum width: each step's toe (or heel) reaches the stance sole."""
    config = config_from_dict(
        {"gait": {"n_steps": 6, "step_length": 0.0, "step_width": 0.14, "turn": 0.3}}
    )
    plan = plan_from_config(config)
    warnings = [w for w in check_plan(plan, TALOS, config) if "overlaps" in str(w)]
    expected = [
        k
        for k in range(len(plan.steps))
        if _soles_intersect(plan.stance_for(k), plan.steps[k], 0.21, 0.13)
    ]
    assert [w.step for w in warnings] == expected and len(expected) >= 4
    assert all(w.setting == "gait.step_width" for w in warnings)
    assert "soles must not intersect" in str(warnings[0])
    # the default width clears the soles at the same turn
    wide = config_from_dict({"gait": {"n_steps": 6, "step_length": 0.0, "turn": 0.3}})
    assert check_plan(plan_from_config(wide), TALOS, wide) == []


def test_fast_swings_name_t_ss_and_the_limit():
    config = config_from_dict({"gait": {"n_steps": 6, "step_length": 0.4, "t_ss": 0.3}})
    plan = plan_from_config(config)
    warnings = [w for w in check_plan(plan, TALOS, config) if w.setting != "dcm.b"]  # (height)
    # lift-off → touchdown: 0.4 m for the first and closing steps, 0.8 m for the others
    lift = plan_footsteps(config.gait)[0]
    expected = []
    for k, step in enumerate(plan.steps):
        distance = np.hypot(*(step.position - lift[step.side].position)[:2])
        lift[step.side] = step
        if distance / 0.3 > TALOS.max_swing_speed_m_s:
            expected.append(k)
    assert [w.step for w in warnings] == expected == [1, 2, 3, 4]
    assert all(w.setting == "gait.t_ss" for w in warnings)
    for word in ("footstep 2", "0.800 m", "2.67 m/s", "1.8 m/s", "gait.t_ss ≥ 0.444 s"):
        assert word in str(warnings[0]), str(warnings[0])


def test_com_height_outside_the_robots_range_is_warned():
    config = Config()
    for b, height in ((0.33, GRAVITY * 0.33**2), (0.25, GRAVITY * 0.25**2)):
        plan, _ = _plan_with(plan_footsteps(config.gait)[1], b=b)
        warnings = check_plan(plan, TALOS, config)
        assert [w.setting for w in warnings] == ["dcm.b"]
        assert f"{height:.3f} m" in str(warnings[0]) and "0.720–0.900 m" in str(warnings[0])


# -- runner ------------------------------------------------------------------------------------


def test_runner_json_lists_the_walked_plans_warnings(tmp_path: Path, capsys) -> None:
    preset = str(PRESETS[0].parent / "walk_forward.toml")
    out = tmp_path / "r.json"
    args = [preset, "--sim", "lip", "--duration", "0.3", "--json", str(out)]
    assert main(args) == 0
    assert json.loads(out.read_text())["warnings"] == []
    assert main([*args, "--set", "gait.t_start=0.2"]) == 0
    warnings = json.loads(out.read_text())["warnings"]
    assert len(warnings) == 1 and "D2" in warnings[0] and "gait.t_start" in warnings[0]
    assert "warning: VRP waypoint 2" in capsys.readouterr().out


def test_runner_refuses_a_b_the_robot_cannot_walk_at(capsys) -> None:
    preset = str(PRESETS[0].parent / "walk_forward.toml")
    assert main([preset, "--sim", "lip", "--set", "dcm.b=0.33"]) == 2
    err = capsys.readouterr().err
    # the range it names holds only accepted values (issue 25: 0.303 s, printed before, is not)
    assert "dcm.b = 0.33" in err and "1.068 m" in err and "0.271 to 0.302 s" in err


def test_stairs_from_feet_settled_in_the_contact_are_not_too_high():
    """The walker plans from the measured feet, a millimetre deep in MuJoCo's soft contact: the
    0.15 m stairs of stairs_up measure 0.151 m from them, within Talos's 0.15 m; 0.16 m does not."""
    config = load_preset(PRESETS[0].parent / "stairs_up.toml")
    spec = load_robot(config.robot.model).spec
    feet, _ = plan_footsteps(config.gait)
    sunk = {s: f.moved(f.position - [0.0, 0.0, 0.001]) for s, f in feet.items()}
    plan = plan_from_config(config, start_feet=sunk)
    assert abs(plan.steps[0].position[2] - sunk[plan.steps[0].side].position[2]) > 0.15
    assert not [w for w in check_plan(plan, spec, config) if w.setting == "gait.step_height"
                or "height change" in w.message]  # fmt: skip
    high = config.replace(terrain={"stairs": {**config.terrain.stairs.model_dump(), "rise": 0.16}})
    plan = plan_from_config(high, start_feet=sunk)
    assert any("height change" in w.message for w in check_plan(plan, spec, high))


def test_numbers_in_warnings_are_sane_over_random_infeasible_settings() -> None:
    """Issue 25: a warning read "legs reach only 0.236 m high … lowers the CoM by 0.647 m" (a
    footstep that step adjustment had moved 0.45 m out).  Over random settings of two robots,
    and plans with one footstep moved up to 0.7 m (as recovery moves them), every number a
    warning states is finite and within what it can physically be: a height the legs reach lies
    within the robot's walking heights, the CoM is never said to be lowered below them, a
    distance or a gap is at most a few metres, a speed and a time are positive."""
    rng = np.random.default_rng(2025)
    seen = 0
    for robot in ("talos", "g1"):
        spec = load_robot(robot).spec
        lo, hi = spec.com_height_range_m
        plans = 0
        while plans < 60:
            data = {
                "robot": {"model": robot},
                "gait": {
                    "step_length": float(rng.uniform(-0.5, 0.5)),
                    "step_width": float(rng.uniform(0.05, 0.6)),
                    "turn": float(rng.uniform(-0.5, 0.5)),
                    "t_ss": float(rng.uniform(0.15, 1.5)),
                    "t_ds": float(rng.uniform(0.03, 0.5)),
                    "t_start": float(rng.uniform(0.15, 2.0)),
                    "n_steps": int(rng.integers(1, 10)),
                },
                "dcm": {"b": float(rng.uniform(*spec.b_range_s))},
            }
            try:
                config = config_from_dict(data)
                plan = plan_from_config(config)
            except ValueError:
                continue
            plans += 1
            candidates = [plan]
            k = int(rng.integers(len(plan.steps)))
            shift = rng.uniform(-0.7, 0.7, 2)
            moved = plan.steps[k].position + np.array([shift[0], shift[1], 0.0])
            candidates.append(plan.with_step(k, moved))  # as step adjustment moves one
            for candidate in candidates:
                for w in check_plan(candidate, spec, config):
                    seen += 1
                    text = w.message
                    numbers = [float(x) for x in re.findall(r"-?\d+\.\d+", text)]
                    assert all(math.isfinite(x) for x in numbers), text
                    assert all(abs(x) < 10.0 for x in numbers), text
                    if m := re.search(r"legs reach only (\d+\.\d+) m high", text):
                        assert lo - 1e-3 <= float(m.group(1)) <= hi + 1e-3, text
                    if m := re.search(r"lowers the CoM by (\d+\.\d+) m", text):
                        dz = GRAVITY * config.dcm.b**2
                        assert 0.0 < float(m.group(1)) <= dz - lo + 1e-3, text
                    if m := re.search(r"(\d+\.\d+) m/s", text):
                        assert float(m.group(1)) > 0.0, text
    assert seen > 100
