"""Crossover recovery steps (issue 24): the crossover region against the robot's kinematics in
MuJoCo, the crossover bound against numerical integration, the strategy on the point mass beyond
the stance-edge bound, references that never jump, crossed stances in the feasibility check, and
a crossing walk of the humanoid without leg-leg contact."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from helpers import rk4

from dcmviz.config import Config, load_preset
from dcmviz.gait import check_plan, plan_from_config
from dcmviz.robots import load_robot
from dcmviz.robots.crossover import (
    reach_beyond_com,
    touchdown_exists,
    touchdown_posture,
    touchdown_problem,
)
from dcmviz.session import Session
from dcmviz.sweep import bounds
from dcmviz.sweep.bounds import (
    crossed_edge_impulse,
    crossed_reach_impulse,
    crossover_bound,
    reference_com,
    stance_edge_bound,
)
from dcmviz.sweep.search import push_window

ROOT = Path(__file__).resolve().parents[1]


def test_crossed_edge_impulse_leaves_the_dcm_on_the_crossed_edge() -> None:
    """RK4 of the pushed LIP (ẍ = (x − p)/b² + F/m) with the CoP p on the stance edge until the
    crossed foot lands and on its edge after: at the bound's impulse the DCM ends on the crossed
    edge once the push is over and the foot down; 5 % more ends outside, 5 % less inside."""
    m, b, T = 90.0, 0.3, 0.2
    stance, crossed = 0.08, 0.30

    def final_dcm(impulse: float, touchdown: float) -> float:
        """RK4 per piece of constant CoP and force (the breaks exactly at their instants)."""
        F = impulse / T
        y = np.array([0.0, 0.0])  # x, ẋ with ξ_0 = 0
        breaks = sorted({0.0, min(T, touchdown), max(T, touchdown)})
        for t0, t1 in zip(breaks, breaks[1:], strict=False):
            cop = stance if t0 < touchdown else crossed
            force = F / m if t0 < T else 0.0
            n = 3000
            h = (t1 - t0) / n

            def f(s: np.ndarray, cop: float = cop, force: float = force) -> np.ndarray:
                return np.array([s[1], (s[0] - cop) / b**2 + force])

            y = rk4(f, y, h, n)
        return y[0] + b * y[1]

    for touchdown in (0.12, 0.35):
        J = crossed_edge_impulse(stance, crossed, touchdown, m, b, T)
        assert abs(final_dcm(J, touchdown) - crossed) < 1e-9, touchdown
        assert final_dcm(1.05 * J, touchdown) > crossed + 1e-3
        assert final_dcm(0.95 * J, touchdown) < crossed - 1e-3


@pytest.mark.parametrize(
    ("reach_edge", "com0", "touchdown"),
    [(0.12, -0.02, 0.15), (0.12, -0.02, 0.35), (0.5, -0.02, 0.2)],  # the last: the region binds
)
def test_crossed_reach_impulse_leaves_the_dcm_on_the_edge_the_legs_reach(
    reach_edge: float, com0: float, touchdown: float
) -> None:
    """RK4 of the pushed LIP (ẍ = (x − p)/b² + F/m, the CoM itself) with the CoP on the stance
    edge until the crossed foot lands, then on the nearer of the region's edge and the CoM's
    position at the landing plus the legs' reach: at the bound's impulse the DCM ends on that
    edge; 5 % more ends outside it, 5 % less inside."""
    m, b, T = 90.0, 0.3, 0.2
    stance, crossed = 0.08, 0.30

    def final(impulse: float) -> tuple[float, float]:
        F = impulse / T
        y = np.array([com0, -com0 / b])  # x, ẋ with ξ_0 = x + b ẋ = 0
        edge = stance
        breaks = sorted({0.0, min(T, touchdown), max(T, touchdown)})
        for t0, t1 in zip(breaks, breaks[1:], strict=False):
            if t0 >= touchdown and edge == stance:
                edge = min(crossed, y[0] + reach_edge)
            force = F / m if t0 < T else 0.0
            n = 3000

            def f(s: np.ndarray, cop: float = edge, force: float = force) -> np.ndarray:
                return np.array([s[1], (s[0] - cop) / b**2 + force])

            y = rk4(f, y, (t1 - t0) / n, n)
        if edge == stance:  # the foot lands as the push ends
            edge = min(crossed, y[0] + reach_edge)
        return y[0] + b * y[1], edge

    J = crossed_reach_impulse(stance, crossed, reach_edge, com0, touchdown, m, b, T)
    xi, edge = final(J)
    assert abs(xi - edge) < 1e-6, (xi, edge)
    xi, edge = final(1.05 * J)
    assert xi > edge + 1e-3
    xi, edge = final(0.95 * J)
    assert xi < edge - 1e-3
    if reach_edge > 0.4:  # the legs reach past the region: the region's bound
        assert J == pytest.approx(crossed_edge_impulse(stance, crossed, touchdown, m, b, T))


def test_the_reference_com_is_the_point_mass_walk_s() -> None:
    """The CoM the crossover bound starts from (the plan's reference, ċ = (ξ_ref − c)/b from
    standing) is where the point mass walking that plan has its CoM, to 1 mm over a walk."""
    config = load_preset(ROOT / "presets" / "walk_forward.toml").replace(
        pushes=[], control={"observer": False}
    )
    plan = plan_from_config(config)
    s = Session(config, backend="lip")
    for t in (1.0, 2.33, 3.91, 4.05, 5.5):
        while s.t < t - 1e-9:
            s.step()
        assert np.linalg.norm(s.tick().state.com[:2] - reference_com(plan, t)) < 1e-3, t


def test_a_crossed_sole_lands_at_most_its_reach_past_the_com() -> None:
    """Talos: a crossed sole lands the reach past the CoM where it was found, and 2 cm further
    past the CoM (twice the reach's resolution) at no base yaw (the posture's free coordinate)
    at any x of either polygon, with the CoM over the stance sole or 5 or 10 cm beyond it: the
    reach is the legs' (the pelvis hangs over the CoM), not the stance foot's, and it is smaller
    than the region's crossing past the stance foot's centre."""
    talos = load_robot("talos")
    region = talos.crossover
    reach, x, com = reach_beyond_com(talos.model, "left", region.polygons)
    assert reach == talos.crossover_reach
    assert 0.05 < reach < -min(float(p[:, 1].min()) for p in region.polygons)
    assert touchdown_exists(talos.model, "left", x, com - reach, com)
    for polygon in region.polygons:
        for x in np.arange(polygon[:, 0].min(), polygon[:, 0].max() + 1e-9, 0.05):
            for com in (0.0, -0.05, -0.1):
                deeper = com - reach - 0.02
                assert not touchdown_exists(talos.model, "left", float(x), deeper, com), (x, com)


def test_talos_s_crossover_bound_is_its_legs_reach_from_the_com() -> None:
    """The humanoid's crossover bound counts the legs' reach past the CoM: below the region's
    alone (the point mass's model with the torso's lever), above the stance-edge bound."""
    config = load_preset(ROOT / "presets" / "walk_forward.toml").replace(
        control={"recovery": "crossover", "observer": False}
    )
    for phase in (0.3, 0.5):
        edge = stance_edge_bound(config, 4, phase, 0.2, math.pi / 2, backend="mujoco")
        with_legs = crossover_bound(config, 4, phase, 0.2, math.pi / 2, backend="mujoco")
        start, _, _ = push_window(config, 4, phase)
        robot, _, pushed, lever = bounds._pushed(
            config, start, math.pi / 2, "mujoco", "torso", True
        )
        half = 0.5 * robot.spec.foot_width_m
        region_only = crossed_edge_impulse(
            pushed.centre + half - pushed.xi0,
            pushed.centre + bounds.reach_across(robot) + half - pushed.xi0,
            pushed.landing_s, robot.spec.mass_kg, config.dcm.b, 0.2, lever,
        )  # fmt: skip
        assert edge < with_legs < region_only, (phase, edge, with_legs, region_only)


def _legs_touch(robot, q: np.ndarray) -> bool:
    """MuJoCo's own collision of the leg capsules at the posture q (Pinocchio order)."""
    scene = robot.mujoco
    data = mujoco.MjData(scene.model)
    data.qpos[:] = scene.qpos_mj(q)
    mujoco.mj_forward(scene.model, data)
    return scene.leg_contacts(data) > 0


def test_crossover_region_is_what_the_legs_reach() -> None:
    """Talos: every vertex of the region (pulled 1 cm inside) is a touchdown the legs reach with
    MuJoCo's leg capsules apart and every joint inside MuJoCo's own ranges; 6 cm beyond the
    region's crossing edge (more across) they do not (joint range, sole or legs in the way)."""
    talos = load_robot("talos")
    region = talos.crossover
    assert len(region.front) >= 3 and len(region.back) >= 3
    model = talos.mujoco.model
    ranges = {
        name: model.jnt_range[model.joint(name).id] for name in talos.joint_names
    }  # MuJoCo's, from the same URDF
    for polygon in region.polygons:
        centre = polygon.mean(axis=0)
        for vertex in polygon:
            x, lateral = vertex + 0.01 * (centre - vertex) / np.linalg.norm(centre - vertex)
            q, residual = touchdown_posture(talos.model, "left", x, lateral)
            assert residual < 1e-6
            for i, name in enumerate(talos.joint_names):
                lo, hi = ranges[name]
                assert lo <= q[7 + i] <= hi, (x, lateral, name)
            assert not _legs_touch(talos, q), (x, lateral)
        # beyond the most crossed edge: the posture does not exist or breaks a rule
        deepest = polygon[np.argmin(polygon[:, 1])]
        assert touchdown_problem(talos.model, "left", float(deepest[0]), deepest[1] - 0.06)


def test_a_crossed_posture_touching_legs_is_seen_by_mujoco() -> None:
    """The check above can fail: a touchdown straight across the stance foot's middle makes
    MuJoCo's leg capsules collide (or the soles overlap), and the region does not hold it."""
    talos = load_robot("talos")
    q, residual = touchdown_posture(talos.model, "left", 0.05, -0.05)
    assert residual < 1e-6
    assert touchdown_problem(talos.model, "left", 0.05, -0.05)
    assert not talos.crossover.contains(0.05, -0.05)


def _survives(strategy: str, impulse: float, phase: float, backend: str = "lip") -> bool:
    config = Config().replace(
        sim={"backend": backend}, control={"recovery": strategy, "observer": False}
    )
    start = push_window(config, 4, phase)[0]
    s = Session(config, backend=backend)
    s.push((0.0, impulse / 0.2, 0.0), 0.2, start=start)
    s.run(start + 3.0)
    return not s.fell


@pytest.mark.parametrize("phase", [0.3, 0.5])
def test_point_mass_crosses_beyond_the_stance_edge_bound(phase: float) -> None:
    """Point mass, 0.2 s pushes at 90° (towards the left stance foot) at 30 % and 50 % of step
    4's single support: multi_step_timing falls just past the stance-edge bound; crossover
    survives 1.2×, 1.3× and 1.35× of it."""
    config = Config().replace(sim={"backend": "lip"}, control={"observer": False})
    bound = stance_edge_bound(config, 4, phase, 0.2, math.pi / 2)
    assert not _survives("multi_step_timing", 1.05 * bound, phase)
    for scale in (1.2, 1.3, 1.35):
        assert _survives("crossover", scale * bound, phase), scale


def test_crossing_keeps_the_references_smooth_and_then_uncrosses() -> None:
    """A crossing walk of the point mass: ξ_adj and the commanded VRP never jump (the footholds
    blend from the uncrossed to the crossed answer), the crossed footstep lands across the stance
    foot inside the region and the next one lands on its own side again."""
    from test_smoothness import jumps, push_rate_steps

    config = Config().replace(
        sim={"backend": "lip"}, control={"recovery": "crossover", "observer": False}
    )
    s = Session(config, backend="lip")
    bound = stance_edge_bound(config, 4, 0.5, 0.2, math.pi / 2)
    start = push_window(config, 4, 0.5)[0]
    s.push((0.0, 1.3 * bound / 0.2, 0.0), 0.2, start=start)
    ticks = []
    s.subscribe(ticks.append)
    s.run(start + 3.0)
    assert not s.fell
    dt = s.backend.control_dt
    f_ext = np.array([k.f_ext for k in ticks])
    rate_step = push_rate_steps(f_ext, s.mass, config.dcm.b, config.control.k_xi, 10.0)
    for name in ("xi_adj", "v_cmd"):
        signal = np.array([getattr(k.command, name) for k in ticks])
        worst = jumps(signal, dt, kink=2.5, rate_step=rate_step)
        assert worst.max() <= 0.0, f"{name} jumps {worst.max() * 100:.2f} cm beyond its rate"
    steps = s.realised_steps()
    lateral = []
    for prev, step in zip(steps, steps[1:], strict=False):
        d = step.position[:2] - prev.position[:2]
        lateral.append((1.0 if step.side == "left" else -1.0) * d[1])  # towards its own side
    crossed = [i for i, w in enumerate(lateral) if w < s.spec.min_step_width_m - 1e-6]
    assert crossed, "no footstep crossed"
    for i in crossed:  # each crossing is followed by a footstep on its own side
        assert i + 1 < len(lateral) and lateral[i + 1] >= s.spec.min_step_width_m - 1e-6
    robot = load_robot("talos")
    assert not [w for w in check_plan(s.plan, s.spec, config, robot.crossover)
                if "across" in w.message]  # fmt: skip


def test_feasibility_knows_crossed_stances() -> None:
    """A plan with one footstep across its stance foot: inside the region it is a crossed
    stance (no warning with the region, a reach warning without it); two crossings in a row or
    one outside the region are warned about."""
    talos = load_robot("talos")
    config = Config()
    plan = plan_from_config(config)
    k = 3  # the right foot steps from the left stance foot
    stance = plan.stance_for(k)
    assert plan.steps[k].side == "right"
    front = talos.crossover.front
    x, lateral = front.mean(axis=0)
    assert lateral < talos.spec.min_step_width_m
    crossed = plan.with_step(k, stance.position + np.array([x, -lateral, 0.0]))

    def reach(plan, region=None) -> list:  # the warnings about footstep k's place (not height)
        return [w for w in check_plan(plan, talos.spec, config, region)
                if w.step == k and w.setting != "dcm.b"]  # fmt: skip

    assert not reach(crossed, talos.crossover)
    assert reach(crossed) and "across" in reach(crossed)[0].message
    far = plan.with_step(k, stance.position + np.array([0.0, 0.05, 0.0]))  # straight across
    assert "outside the crossover region" in reach(far, talos.crossover)[0].message
    # the footstep after the crossed one crossing back over it: the legs must uncross first
    nxt = crossed.steps[k]
    twice = crossed.with_step(k + 1, nxt.position + np.array([x, lateral, 0.0]))
    assert any("uncross" in w.message for w in check_plan(twice, talos.spec, config, talos.crossover)
               if w.step == k + 1)  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("impulse", [23.0, 26.0, 29.0])
def test_talos_crosses_without_its_legs_touching(impulse: float) -> None:
    """Talos in MuJoCo, a 0.2 s push towards its stance foot at mid single support: the
    crossover strategy puts the swinging foot across in front of the stance foot, and MuJoCo
    reports no contact between the legs at any tick (the whole-body QP keeps them apart).
    Survived over a range of impulses (measured: 20-29 N s survived, 32 falls), not one value."""
    config = load_preset(ROOT / "presets" / "walk_forward.toml").replace(
        pushes=[], control={"recovery": "crossover", "observer": False}
    )
    start = push_window(config, 4, 0.5)[0]
    s = Session(config, backend="mujoco")
    s.push((0.0, impulse / 0.2, 0.0), 0.2, start=start)
    contacts, modes = 0, set()
    while s.t < start + 2.5 and not s.fell:
        s.step()
        contacts += s.backend.scene.leg_contacts(s.backend.data)
        modes.add(s.walker.strategy.mode)
    assert not s.fell and "front" in modes and contacts == 0
