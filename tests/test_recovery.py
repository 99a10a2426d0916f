"""Multi-step adjustment (dcmviz.recovery): the QP against a dense solve of eq. (28)."""

from __future__ import annotations

import numpy as np
import pytest

from dcmviz import recovery
from dcmviz.config import Config
from dcmviz.gait import Footstep, plan_from_config
from dcmviz.recovery import Candidate
from dcmviz.robots import load_robot
from dcmviz.session import Session


def candidates_from_dense(plan, k: int, t: float, n: int = 3) -> list[Candidate]:
    """Leverages c_j from the dense A_xi_ref_0 (eq. 20) and S_adj (eq. 29), row φ_fa,j (eq. 28)."""
    A = plan.preview.A_xi_ref_0  # (3 n_phi, 3 n_wp)
    out = []
    for j in range(k, k + n):
        S = np.kron(plan.selection(j)[:, None], np.eye(3))  # (3 n_wp, 3)
        if plan.is_closing_step(j):
            rows = plan.preview.A_xi_ref_T[-3:]  # the plan's end: ξ_ref_T of the last phase
            instant = plan.t_end
        else:
            phi = plan.first_affected_phase(j)
            rows = A[3 * phi : 3 * phi + 3]
            instant = plan.phase_start(phi)
        block = rows @ S  # = c_j I₃
        np.testing.assert_allclose(block, block[0, 0] * np.eye(3), atol=1e-12)
        out.append(Candidate(plan.steps[j], float(block[0, 0]), instant - t))
    return out


@pytest.mark.parametrize("order", [1, 3, 5])
def test_qp_equals_dense_weighted_least_squares_when_constraints_are_inactive(order) -> None:
    config = Config().replace(dcm={"order": order})
    plan = plan_from_config(config)
    k, t, b = 3, plan.phase_start(6) + 0.1, config.dcm.b
    cands = candidates_from_dense(plan, k, t)
    error = np.array([0.004, -0.006, 0.0])  # small: no reach limit is touched
    got = recovery.solve(cands, plan.stance_for(k), error, load_robot("talos").spec, 0.3, b)
    # dense: minimise Σ ω_j |Δv_j|² + ρ |ξ̃ − C Δv|² as one stacked least-squares problem
    lead = np.array([c.lead_time_s for c in cands])
    omega = np.exp(np.maximum(lead - lead[0], 0.0) / b)
    C = np.hstack([c.leverage * np.eye(2) for c in cands])
    rho = recovery.qp.CONDITION_WEIGHT
    M = np.vstack([np.sqrt(rho) * C, np.diag(np.repeat(np.sqrt(omega), 2))])
    rhs = np.concatenate([np.sqrt(rho) * error[:2], np.zeros(2 * len(cands))])
    dense = np.linalg.lstsq(M, rhs, rcond=None)[0].reshape(-1, 2)
    np.testing.assert_allclose(np.array(got)[:, :2], dense, atol=1e-9)
    closed = recovery.least_squares(cands, error, b)
    np.testing.assert_allclose(np.array(got), np.array(closed), atol=1e-9)
    # eq. (31) holds: the adjusted references cancel the error at the instants
    assert np.linalg.norm(C @ dense.ravel() - error[:2]) < 1e-3 * np.linalg.norm(error)


def test_reach_limits_hold_and_the_next_footstep_takes_the_rest() -> None:
    config = Config()
    plan = plan_from_config(config)
    spec = load_robot("talos").spec
    k = 3  # a footstep of the right foot (first swing is the left one)
    t = plan.phase_start(2 * k + 2) + 0.1
    cands = candidates_from_dense(plan, k, t)
    side = plan.steps[k].side
    towards_stance = np.array([0.0, 0.3 if side == "right" else -0.3, 0.0])
    dvs = recovery.solve(cands, plan.stance_for(k), towards_stance, spec, 0.4, config.dcm.b)
    stance = plan.stance_for(k)
    landed = plan.steps[k].position + dvs[0]
    lateral = (
        -(landed[1] - stance.position[1]) if side == "right" else landed[1] - stance.position[1]
    )
    assert lateral >= spec.min_step_width_m - 1e-9  # no leg crossing
    assert np.linalg.norm(dvs[1][:2]) > 0.05  # the footstep after it steps out instead


def test_multi_step_walk_is_nominal_undisturbed_and_recovers_pushes() -> None:
    config = Config().replace(sim={"backend": "lip"}, control={"recovery": "multi_step"})
    s = Session(config, backend="lip")
    s.run(s.plan.duration + 1.0)
    assert not s.fell and s.metrics.max_dcm_error_m < 1e-3
    s = Session(config, backend="lip")
    s.push((0.0, -150.0, 0.0), 0.2, start=3.95)
    s.run(12.0)
    assert not s.fell


@pytest.mark.parametrize("strategy", ["next_step", "multi_step"])
def test_tick_shows_the_footstep_after_the_adjusted_one_when_it_takes_the_rest(strategy) -> None:
    """A push towards the stance foot: the swinging foot may not cross, so the footstep after it
    steps out; the tick carries both for the dashboard's ghosts."""
    config = Config().replace(sim={"backend": "lip"}, control={"recovery": strategy})
    s = Session(config, backend="lip")
    seen = []
    s.subscribe(lambda tick: seen.append(tick.recovery_step) if tick.recovery_step else None)
    s.push((0.0, 150.0, 0.0), 0.2, start=3.95)  # left, towards the left stance foot
    s.run(5.0)
    assert seen, "the footstep after the adjusted one never moved"
    assert max(step.position[1] for step in seen) > 0.085 + 0.05  # the left foot steps out


# -- honest leverages (issue 11, second part) ---------------------------------------------------


def test_cop_capacity_is_what_a_held_cop_offset_removes() -> None:
    """ε = (1 − e^{−τ/b}) δ: a CoP offset δ held τ seconds brings the DCM onto ξ_adj (numerical
    integration of ε̇ = (ε − δ)/b, the DCM dynamics relative to a reference, eq. 2)."""
    b, tau, delta = 0.3, 0.45, np.array([0.03, -0.05])
    eps = (1.0 - np.exp(-tau / b)) * delta
    n = 20000
    h = tau / n
    for _ in range(n):  # RK2
        mid = eps + 0.5 * h * (eps - delta) / b
        eps = eps + h * (mid - delta) / b
    assert np.linalg.norm(eps) < 1e-6


def test_capacity_makes_the_later_footsteps_take_what_the_cop_cannot() -> None:
    """With the capacity, the QP's ε = ξ̃ − Σ a_j(t) Δv_j, a_j(t) from the dense dcm_weights
    (eqs. 22, 33–35), lies in the capacity whenever the footsteps can make it; without it the
    own-instant leverages leave far more to the CoP."""
    config = Config()
    plan = plan_from_config(config)
    spec = load_robot("talos").spec
    k = 3
    t = plan.phase_start(2 * k + 2) + 0.35  # mid single support of footstep k
    local = t - plan.t0
    w = plan.preview.dcm_weights(local)
    cands = [
        Candidate(c.nominal, c.leverage, c.lead_time_s, now_leverage=float(w @ plan.selection(j)))
        for j, c in enumerate(candidates_from_dense(plan, k, t), start=k)
    ]
    a = np.array([c.now_leverage for c in cands])
    assert a[0] > 5 * a[1] > 0.0  # the later footstep moves ξ_adj now far less
    capacity = recovery.Capacity(np.eye(2), np.array([-0.02, -0.02]), np.array([0.02, 0.02]))
    error = np.array([0.05, 0.0, 0.0])  # forward: every footstep may move
    sol = recovery.solve_full(
        cands, plan.stance_for(k), error, spec, 0.4, config.dcm.b, capacity=capacity
    )
    eps = error[:2] - sum(c.now_leverage * dv[:2] for c, dv in zip(cands, sol.dv, strict=True))
    assert np.all(eps >= capacity.lo - 1e-6) and np.all(eps <= capacity.hi + 1e-6)
    assert np.linalg.norm(sol.slack) < 1e-6
    loose = recovery.solve(cands, plan.stance_for(k), error, spec, 0.4, config.dcm.b)
    eps_loose = error[:2] - sum(c.now_leverage * dv[:2] for c, dv in zip(cands, loose, strict=True))
    assert eps_loose[0] > 0.02 + 1e-3  # the paper's persistence condition alone: not capturable


def _survives(strategy: str, impulse: float, angle_deg: float) -> bool:
    config = Config().replace(
        sim={"backend": "lip"},
        control={"recovery": strategy, "observer": False},
    )
    s = Session(config, backend="lip")
    a = np.radians(angle_deg)
    force = impulse / 0.2
    start = plan_from_config(config).phase_start(8) + 0.35  # mid single support, step 4
    s.push((force * np.cos(a), force * np.sin(a), 0.0), 0.2, start=start)
    s.run(start + 3.0)
    return not s.fell


def test_step_timing_walks_nominal_undisturbed_and_catches_a_push_towards_the_stance_foot() -> None:
    config = Config().replace(sim={"backend": "lip"}, control={"recovery": "multi_step_timing"})
    s = Session(config, backend="lip")
    s.run(s.plan.duration + 1.0)
    assert not s.fell and s.metrics.max_dcm_error_m < 1e-3
    np.testing.assert_array_equal(s.plan.preview.durations, s.nominal_plan.preview.durations)
    # towards the stance foot (left, step 4 swings the right foot): the paper's single step
    # cannot cross the stance leg; a short in-place step and a quick wide one can
    assert not _survives("next_step", 34.0, 90.0)
    assert _survives("multi_step_timing", 34.0, 90.0)


# -- priority projection (issue 11, third part) ------------------------------------------------


def test_a_vrp_outside_the_support_keeps_its_lateral_part() -> None:
    """In double support (stance ahead-left of a foot that just landed beside it) a VRP asked far
    out forward-left: the nearest point of the hull gives up most of its lateral part, the
    priority projection keeps the stance sole's outer edge (and is inside the hull)."""
    from dcmviz.gait.terrain import Terrain
    from dcmviz.recovery import MultiStepTiming
    from dcmviz.robots.geometry import convex_hull, project_to_polygon, sole_corners

    talos = load_robot("talos")
    spec = talos.spec
    strategy = MultiStepTiming(talos, Terrain(), 0.3, 0.005)
    placed = {
        "left": Footstep("left", np.array([0.6, 0.085, 0.0]), 0.0),
        "right": Footstep("right", np.array([0.8, -0.055, 0.0]), 0.0),
    }
    v = np.array([1.0, 0.3, 0.9])
    hull = convex_hull(
        np.vstack([sole_corners(f.position, 0.0, spec.foot_length_m, spec.foot_width_m)
                   for f in placed.values()])
    )  # fmt: skip
    nearest, _ = project_to_polygon(v[:2], hull)
    got = strategy.shape_vrp(v, {"left": True, "right": True}, placed)
    assert project_to_polygon(got[:2], hull)[1] < 1e-9
    assert got[1] > nearest[1] + 0.05
    assert got[1] > 0.085 + 0.5 * spec.foot_width_m - 0.02
    assert got[2] == v[2]
    inside = np.array([0.7, 0.0, 0.9])
    both = {"left": True, "right": True}
    np.testing.assert_array_equal(strategy.shape_vrp(inside, both, placed), inside)


def test_the_lateral_priority_support_moves_with_the_observers_shift() -> None:
    """With the observer's reference shift s (eqs. 47–49) the contact CoP lies −s from the VRP,
    so the support the commanded VRP is kept in is the soles moved by s: shape_vrp(v, s) =
    shape_vrp(v − s) + s (horizontal part of s), and a VRP that is on the soles' image is kept."""
    from dcmviz.gait.terrain import Terrain
    from dcmviz.recovery import MultiStepTiming

    talos = load_robot("talos")
    strategy = MultiStepTiming(talos, Terrain(), 0.3, 0.005)
    placed = {
        "left": Footstep("left", np.array([0.6, 0.085, 0.0]), 0.0),
        "right": Footstep("right", np.array([0.8, -0.055, 0.0]), 0.0),
    }
    both = {"left": True, "right": True}
    shift = np.array([0.01, -0.12, -0.03])
    offset = np.array([0.01, -0.12, 0.0])
    for v in (np.array([1.0, 0.3, 0.9]), np.array([0.7, -0.3, 0.9]), np.array([0.6, 0.2, 0.9])):
        got = strategy.shape_vrp(v, both, placed, shift)
        np.testing.assert_allclose(got, strategy.shape_vrp(v - offset, both, placed) + offset)
    on_image = np.array([0.6, 0.085 - 0.12, 0.9])  # the left sole's centre, moved by the shift
    np.testing.assert_array_equal(strategy.shape_vrp(on_image, both, placed, shift), on_image)
    far = np.array([0.6, 0.085 + 0.05, 0.9])  # on the left sole, beyond its image
    assert strategy.shape_vrp(far, both, placed, shift)[1] < far[1] - 0.05
    assert strategy.shape_vrp(far, both, placed)[1] == pytest.approx(far[1])


@pytest.mark.parametrize("strategy_name", ["multi_step_timing", "crossover"])
def test_timing_choice_is_the_same_with_the_observers_shift(strategy_name: str) -> None:
    """Under a held force the observer shifts ξ_ref and v_ref by s (eqs. 47–49) and the contact
    CoP lies −s from the VRP: the same DCM error relative to the shifted reference is the same
    recovery problem.  The re-timing's choice must not depend on a held s (it compared ξ with
    the soles themselves in its capture term: a 25 % pull on Talos leaned ξ 0.2 m off them,
    the timing QP stretched the phases and Talos fell where next_step walks).  A push's shift
    is not held (test_sweep_bounds: the point mass with the observer survives 85 % of its
    stance-edge bound)."""
    config = Config().replace(sim={"backend": "lip"}, control={"recovery": strategy_name})
    s = Session(config, backend="lip")
    plan = s.plan
    s.run(plan.phase_start(8) + 0.3)  # single support of footstep 4 (the right foot swings)
    t = s.t
    error = np.array([0.01, 0.07, 0.0])  # towards the stance foot: the timing is questioned
    shift = np.array([0.02, -0.15, -0.01])
    chosen = []
    for offset in (np.zeros(3), shift):
        walker = s.walker.copy()
        walk, strategy = walker.walk, walker.strategy
        local = t - walk.plan.t0
        xi = walk.plan.preview.dcm(local) + offset + error
        strategy.adjust(walk, t, local, error, config.control.max_step_adjustment)
        assert strategy.last_slack > 1e-3  # the QP leaves the CoP short: retime compares
        retimed = strategy.retime(
            walk, t, xi, offset, config.control.max_step_adjustment, held=offset
        )
        assert retimed is not None
        chosen.append((strategy._timing_target.copy(), retimed.preview.durations.copy()))
    np.testing.assert_allclose(chosen[1][0], chosen[0][0], atol=1e-12)
    np.testing.assert_allclose(chosen[1][1], chosen[0][1], atol=1e-12)


@pytest.mark.parametrize("order", [1, 3, 5])
def test_the_cops_credit_in_double_support_is_the_whole_sole_about_the_nominal_vrp(order) -> None:
    """MultiStep.capacity while an undisturbed G1 walks (6 cm wide soles, where a few mm count):
    in every double support the box the CoP is credited with follows the nominal VRP along its
    own S-curve, so at every tick it is the sole's full box (less the margin) about that VRP,
    times 1 − e^{−τ/b}, on both sides.  Moved linearly in time instead, the box lagged the VRP
    by a third of a phase in mid-transfer and the credit on one side fell to 0 (a CoP shortfall
    from nothing)."""
    from dcmviz.recovery import multi_step

    spec = load_robot("g1").spec
    config = Config().replace(
        robot={"model": "g1"},
        sim={"backend": "lip"},
        dcm={"order": order, "b": spec.b_nominal_s},
        gait={"step_length": 0.15, "step_width": round(spec.foot_spacing_m, 3), "n_steps": 6},
        control={"recovery": "multi_step", "observer": False},
    )
    s = Session(config, backend="lip")
    g = 1.0 - np.exp(-multi_step.CAPACITY_TIME_CONSTANTS)
    half = 0.5 * np.array([spec.foot_length_m, spec.foot_width_m])
    margin = np.array([multi_step.capacity_margin(spec.foot_length_m),
                       multi_step.capacity_margin(spec.foot_width_m)])  # fmt: skip
    want = g * (half - margin)  # the yaw is 0: the box's axes are the world's
    seen = 0
    while s.t < s.plan.duration - 0.01:
        s.step()
        walk, strategy = s.walker.walk, s.walker.strategy
        plan = walk.plan
        if plan.contact(s.t).kind != "ds":
            continue
        cap = strategy.capacity(walk, plan, s.t, s.t - plan.t0)
        np.testing.assert_allclose(cap.hi, want, atol=1e-6, err_msg=f"t = {s.t:.3f}")
        np.testing.assert_allclose(cap.lo, -want, atol=1e-6, err_msg=f"t = {s.t:.3f}")
        seen += 1
    assert seen * s.backend.control_dt > 0.9  # the double supports of the walk were read


def test_the_sole_box_is_the_box_of_the_soles_corners_and_kept_per_placement() -> None:
    """MultiStep.sole_box (closed form, kept per placement) against the box of the soles' corners
    (geometry.sole_corners, the capacity margin taken off the sole), for one and two soles at
    random positions and yaws: within an ulp (numpy's matrix product may fuse the corners'
    multiply-adds; at yaw 0, as on the presets, they are equal to the bit); a second call for the
    same placement returns the kept arrays, read-only, and a different placement another box."""
    from dcmviz.recovery import multi_step
    from dcmviz.robots.geometry import sole_corners

    robot = load_robot("talos")
    strategy = recovery.make_strategy("multi_step", robot, None, 0.3, 0.002)
    spec = robot.spec
    length = spec.foot_length_m - 2 * multi_step.capacity_margin(spec.foot_length_m)
    width = spec.foot_width_m - 2 * multi_step.capacity_margin(spec.foot_width_m)
    rng = np.random.default_rng(3)
    for _ in range(300):
        feet = [
            Footstep(side, np.array([*rng.uniform(-2.0, 2.0, 2), 0.1]), float(rng.uniform(-4, 4)))
            for side in ("left", "right")[: int(rng.integers(1, 3))]
        ]
        corners = np.vstack([sole_corners(f.position, f.yaw, length, width) for f in feet])
        lo, hi = strategy.sole_box(feet)
        np.testing.assert_allclose(lo, corners.min(axis=0), rtol=0.0, atol=1e-15)
        np.testing.assert_allclose(hi, corners.max(axis=0), rtol=0.0, atol=1e-15)
        again = strategy.sole_box([Footstep(f.side, f.position.copy(), f.yaw) for f in feet])
        assert again[0] is lo and again[1] is hi and not lo.flags.writeable
    moved = [Footstep("left", feet[0].position + [1e-3, 0.0, 0.0], feet[0].yaw)]
    assert strategy.sole_box(moved)[0][0] == pytest.approx(strategy.sole_box(feet[:1])[0][0] + 1e-3)
    flat = [Footstep("left", np.array([0.3, -0.1, 0.0]), 0.0)]
    corners = sole_corners(flat[0].position, 0.0, length, width)
    np.testing.assert_array_equal(strategy.sole_box(flat)[0], corners.min(axis=0))


@pytest.mark.parametrize("centre", [(0.0, 0.0), (0.05, 0.13), (-0.08, -0.1)])
def test_chained_adjustment_boxes_against_a_general_solver(centre) -> None:
    """Sideways each footstep's ±max box is centred where the footstep before it moved (the first
    one's where the foot it steps from landed, ``centre``), forwards round its nominal place:
    the QP's answer for a large error, the reach rows off, equals a bounded least-squares solve
    of the same cost in u = (Δv_x,i, Δv_y,i − Δv_y,i−1) (Δv_y,−1 = centre_y), where those boxes
    are simple bounds |u| ≤ max (scipy's ``lsq_linear``; the plan walks along x)."""
    from scipy.optimize import lsq_linear

    config = Config()
    plan = plan_from_config(config)
    b, k = config.dcm.b, 3
    t = plan.phase_start(2 * k + 2) + 0.1
    cands = candidates_from_dense(plan, k, t)
    spec, limit = load_robot("talos").spec, 0.2
    error = np.array([0.35, 0.5, 0.0])  # far beyond what ±0.2 m boxes round Δv = 0 can take
    got = recovery.qp.solve_full(
        cands, plan.stance_for(k), error, spec, limit, b, constrained=False, centre=centre
    ).dv
    n = len(cands)
    lead = np.array([c.lead_time_s for c in cands])
    omega = np.exp(np.maximum(lead - lead[0], 0.0) / b)
    C = np.hstack([c.leverage * np.eye(2) for c in cands])
    rho = recovery.qp.CONDITION_WEIGHT
    # ‖M Δv − r‖² = Σ ω_j |Δv_j|² + ρ |ξ̃ − C Δv|², Δv = c₀ + L u (L: cumulative sums)
    M = np.vstack([np.sqrt(rho) * C, np.diag(np.repeat(np.sqrt(omega), 2))])
    r = np.concatenate([np.sqrt(rho) * error[:2], np.zeros(2 * n)])
    assert all(c.nominal.yaw == 0.0 for c in cands)
    L = np.kron(np.eye(n), np.diag([1.0, 0.0])) + np.kron(
        np.tril(np.ones((n, n))), np.diag([0.0, 1.0])
    )
    c0 = np.tile([0.0, centre[1]], n)
    ref = lsq_linear(M @ L, r - M @ c0, bounds=(-limit, limit), tol=1e-14)
    assert ref.success
    np.testing.assert_allclose(np.array(got)[:, :2].ravel(), c0 + L @ ref.x, atol=1e-7)
    dv = np.array(got)[:, :2]
    sideways = np.diff(np.r_[centre[1], dv[:, 1]])
    assert np.all(np.abs(dv[:, 0]) <= limit + 1e-9) and np.all(np.abs(sideways) <= limit + 1e-9)
    assert np.any(np.abs(sideways) > limit - 1e-6)  # the error is large enough to reach an edge
