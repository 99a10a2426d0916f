"""Whole-body QP: its answer checked against Pinocchio's dynamics and the contact constraints."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from dcmviz import GRAVITY
from dcmviz.robots import SIDES, load_robot
from dcmviz.sim.wbc import Gains, WholeBodyController
from dcmviz.walker.state import FootTarget, WalkerCommand

E_Z = np.array([0.0, 0.0, 1.0])


def _state(robot, seed=0):
    rng = np.random.default_rng(seed)
    q = robot.q_nominal.copy()
    q[7:] += rng.normal(scale=0.02, size=robot.nu)
    v = rng.normal(scale=0.1, size=robot.nv)
    return q, v


def _command(robot, support, contact_force, feet):
    zero = np.zeros(3)
    swing = next((s for s in SIDES if not support[s]), None)
    return WalkerCommand(
        t=0.0,
        support=support,
        feet={s: FootTarget(position=np.asarray(p, float)) for s, p in feet.items()},
        swing_side=swing,
        com_force=contact_force - robot.mass * GRAVITY * E_Z,
        contact_force=np.asarray(contact_force, float),
        xi=zero,
        xi_ref=zero,
        xi_adj=zero,
        v_ref=zero,
        v_cmd=zero,
        f_hat=zero,
    )


def _feet(robot, q):
    model, data = robot.pin_model, robot.pin_model.createData()
    pin.framesForwardKinematics(model, data, q)
    return {s: data.oMf[robot.sole_frames[s]].translation.copy() for s in SIDES}


def _check_dynamics_and_constraints(robot, wbc, q, v, sol, active):
    """M q̈ + h = Sᵀτ + Σ Jᵀ w (Pinocchio, computed here) and the contact/torque constraints."""
    model, data = robot.pin_model, robot.pin_model.createData()
    M = pin.crba(model, data, q)
    h = pin.rnea(model, data, q, v, np.zeros(model.nv))
    h[6:] += robot.damping * v[6:]
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    rhs = np.zeros(model.nv)
    rhs[6:] = sol.tau
    for s in SIDES:
        J = pin.getFrameJacobian(model, data, robot.sole_frames[s], pin.LOCAL_WORLD_ALIGNED)
        rhs += J.T @ sol.wrenches[s]
    np.testing.assert_allclose(M @ sol.qdd + h, rhs, atol=1e-5 * robot.mass * GRAVITY)
    g = wbc.gains
    for s in SIDES:
        w = sol.wrenches[s]
        if not active[s]:
            np.testing.assert_allclose(w, 0.0, atol=1e-9)
            continue
        R = data.oMf[robot.sole_frames[s]].rotation
        f, tau = R.T @ w[:3], R.T @ w[3:]
        tol = 1e-6 * robot.mass * GRAVITY
        assert f[2] >= g.min_normal_force - tol
        assert abs(f[0]) <= g.friction * f[2] + tol
        assert abs(f[1]) <= g.friction * f[2] + tol
        cop = np.array([-tau[1], tau[0]]) / f[2]
        assert abs(cop[0]) <= robot.foot_length / 2 + 1e-6
        assert abs(cop[1]) <= robot.foot_width / 2 + 1e-6
    assert np.all(np.abs(sol.tau) <= robot.torque_limit + 1e-6)


@pytest.mark.parametrize("name", ["talos", "g1"])
def test_double_support_realises_the_contact_force(name):
    robot = load_robot(name)
    wbc = WholeBodyController(robot)
    q, v = _state(robot)
    ctx = wbc.kinematics.context(q, v)
    force = robot.mass * GRAVITY * E_Z + np.array([15.0, -10.0, 20.0])
    cmd = _command(robot, {"left": True, "right": True}, force, _feet(robot, q))
    sol = wbc.solve(ctx, cmd, {"left": True, "right": True})
    assert sol.ok
    _check_dynamics_and_constraints(robot, wbc, q, v, sol, {"left": True, "right": True})
    total = sol.wrenches["left"][:3] + sol.wrenches["right"][:3]
    np.testing.assert_allclose(total, force, atol=0.02 * robot.mass * GRAVITY)


@pytest.mark.parametrize("name", ["talos", "g1"])
def test_single_support_holds_the_stance_foot_and_lifts_the_swing_foot(name):
    robot = load_robot(name)
    wbc = WholeBodyController(robot)
    q, v = _state(robot, seed=1)
    ctx = wbc.kinematics.context(q, v)
    feet = _feet(robot, q)
    feet["left"] = feet["left"] + np.array([0.05, 0.0, 0.05])  # swing target ahead and up
    com = ctx.com
    # VRP over the right sole: contact force along (x - v) keeps the CoP inside that foot
    vrp = feet["right"] + np.array([0.0, 0.0, robot.com_height])
    b2 = robot.com_height / GRAVITY
    force = robot.mass / b2 * (com - vrp) + robot.mass * GRAVITY * E_Z
    cmd = _command(robot, {"left": False, "right": True}, force, feet)
    sol = wbc.solve(ctx, cmd, {"left": True, "right": True})  # left still touches: no wrench
    assert sol.ok
    active = {"left": False, "right": True}
    _check_dynamics_and_constraints(robot, wbc, q, v, sol, active)
    model, data = robot.pin_model, robot.pin_model.createData()
    pin.forwardKinematics(model, data, q, v, sol.qdd)
    pin.updateFramePlacements(model, data)
    acc_r = pin.getFrameClassicalAcceleration(
        model, data, robot.sole_frames["right"], pin.LOCAL_WORLD_ALIGNED
    ).vector
    vel_r = pin.getFrameVelocity(model, data, robot.sole_frames["right"], pin.LOCAL_WORLD_ALIGNED)
    np.testing.assert_allclose(acc_r, -wbc.gains.kd_stance * vel_r.vector, atol=1e-6)
    acc_l = pin.getFrameClassicalAcceleration(
        model, data, robot.sole_frames["left"], pin.LOCAL_WORLD_ALIGNED
    ).linear
    assert acc_l[2] > 0.0 and acc_l[0] > 0.0  # the swing foot accelerates towards its target


def test_infeasible_demand_keeps_constraints():
    """A force the feet cannot realise (CoP far outside, pulling down) is clipped, not obeyed."""
    robot = load_robot("talos")
    wbc = WholeBodyController(robot, Gains())
    q, v = _state(robot, seed=2)
    ctx = wbc.kinematics.context(q, v)
    force = np.array([2000.0, 0.0, -300.0])
    cmd = _command(robot, {"left": True, "right": True}, force, _feet(robot, q))
    sol = wbc.solve(ctx, cmd, {"left": True, "right": True})
    assert sol.ok  # the force is a task: the QP stays feasible and gives what the feet can
    _check_dynamics_and_constraints(robot, wbc, q, v, sol, {"left": True, "right": True})
    total = sol.wrenches["left"][:3] + sol.wrenches["right"][:3]
    assert total[2] > 0.0  # the feet push, they cannot pull the robot down
    assert total[0] < 0.5 * force[0]  # the friction cones (checked per sole above) clip it


def test_failed_qp_holds_the_last_torques():
    robot = load_robot("talos")
    wbc = WholeBodyController(robot)
    q, v = _state(robot)
    ctx = wbc.kinematics.context(q, v)
    feet = _feet(robot, q)
    good = wbc.solve(
        ctx,
        _command(robot, {"left": True, "right": True}, robot.mass * GRAVITY * E_Z, feet),
        {"left": True, "right": True},
    )
    bad = wbc.solve(
        ctx,
        _command(robot, {"left": True, "right": True}, np.array([np.nan, 0.0, 0.0]), feet),
        {"left": True, "right": True},
    )
    assert good.ok and not bad.ok
    np.testing.assert_array_equal(bad.tau, good.tau)


def test_joint_limit_bounds_keep_a_joint_inside_its_range():
    """Opt-in joint-range bounds: a knee moving fast towards its stop is decelerated,
    q + q̇ T + ½ q̈ T² ≥ q_lo + margin."""
    robot = load_robot("talos")
    gains = Gains(joint_limits=True)
    wbc = WholeBodyController(robot, gains)
    q, v = _state(robot)
    knee = robot.joint_names.index("leg_left_4_joint")
    q[7 + knee] = 0.1
    v[6 + knee] = -3.0  # rad/s towards the stop at 0
    ctx = wbc.kinematics.context(q, v)
    cmd = _command(
        robot, {"left": True, "right": True}, robot.mass * GRAVITY * E_Z, _feet(robot, q)
    )
    sol = wbc.solve(ctx, cmd, {"left": False, "right": True})
    assert sol.ok
    T = gains.joint_limit_horizon
    ahead = q[7 + knee] + v[6 + knee] * T + 0.5 * sol.qdd[6 + knee] * T * T
    assert ahead >= gains.joint_limit_margin - 1e-6


def test_the_reused_daqp_workspace_solves_as_a_fresh_solve_each_tick() -> None:
    """The controller keeps one daqp workspace and updates its numbers each tick (issue 23):
    over the start of a walk (double support, the weight shift, single support) with a failed
    QP (NaN) in between, each tick's solution equals that of ``daqp.solve``, which sets up a
    workspace afresh, on the same matrices."""
    import dataclasses
    from pathlib import Path

    import daqp

    from dcmviz.config import load_preset
    from dcmviz.session import Session

    preset = Path(__file__).resolve().parents[1] / "presets" / "walk_forward.toml"
    session = Session(load_preset(preset), backend="mujoco")
    wbc = session.backend.wbc
    reused = wbc._daqp_solve
    checked: list[tuple[int, int, bool]] = []
    swings = set()

    def both(H, c, A, sense):
        x, _, flag, _ = daqp.solve(H, c, A, wbc._bounds_up, wbc._bounds_lo, sense,
                                   rho_soft=wbc._rho_soft)  # fmt: skip
        out = reused(H, c, A, sense)
        checked.append((flag, out[2], bool(np.array_equal(out[0], x, equal_nan=True))))
        return out

    wbc._daqp_solve = both
    for k in range(800):  # 1.6 s: standing, the weight shift, the first single support
        if k == 300:  # one QP that fails in the middle of it
            command = dataclasses.replace(
                session.last_command, contact_force=np.array([np.nan, 0.0, 0.0])
            )
            assert not wbc.solve(session.backend._ctx, command, {s: True for s in SIDES}).ok
        swings.add(session.step().swing_side)
    assert len(checked) == 801 and {"left", None} <= swings
    assert all(f1 == f2 for f1, f2, _ in checked)
    assert all(same for *_, same in checked)  # the same numbers, bit for bit (NaN included)


def test_each_tick_qp_is_the_dense_sum_of_its_tasks_and_constraints() -> None:
    """The QP a tick solves, built block by block into preallocated arrays (issue 23), equals the
    textbook dense assembly from the same tasks and constraints: H = Σ_k w_k A_kᵀ A_k + the
    regularisation (q̈, the forces, the moments as their corner forces), c = −Σ_k w_k A_kᵀ b_k,
    the rows stacked, all scaled by D = diag(1, m) — and τ is M[6:] q̈ + h[6:] − Σ J_i[:, 6:]ᵀ w_i
    at the answer.  Over the start of a walk and a push (double and single supports)."""
    from pathlib import Path

    from dcmviz.config import load_preset
    from dcmviz.session import Session

    preset = Path(__file__).resolve().parents[1] / "presets" / "g1_push.toml"
    session = Session(load_preset(preset), backend="mujoco")
    wbc = session.backend.wbc
    robot, lay = wbc.robot, wbc.layout
    nv, nx = lay.nv, lay.nx
    solve = wbc.solve
    checked = {"single": 0, "double": 0}

    def reference(ctx, cmd):
        H = np.diag(wbc._reg)
        ax, ay = robot.foot_length / 2, robot.foot_width / 2
        for s in SIDES:
            f = lay.wrench[s].start
            H[f : f + 3, f : f + 3] += wbc._wrench_reg * np.eye(3)
            R = ctx.sole_rotation[s]
            moments = R @ np.diag([1 / ay**2, 1 / ax**2, 1 / (ax**2 + ay**2)]) @ R.T
            H[f + 3 : f + 6, f + 3 : f + 6] += wbc._wrench_reg * moments
        c = np.zeros(nx)
        for task in wbc.tasks:
            out = task.compute(ctx, cmd)
            if out is None:
                continue
            A, b = (np.array(x, dtype=float) for x in out)
            assert A.shape == (len(b), nx)
            H += task.weight * A.T @ A
            c -= task.weight * A.T @ b
        d = np.ones(nx)
        d[nv:] = robot.mass
        return H * np.outer(d, d), c * d, wbc._A * d

    def checking(ctx, cmd, in_contact):
        sol = solve(ctx, cmd, in_contact)
        H, c, A = reference(ctx, cmd)
        scale = np.abs(H).max()
        np.testing.assert_allclose(wbc._H_s, H, rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(wbc._c_s, c, rtol=0, atol=1e-12 * max(1.0, np.abs(c).max()))
        np.testing.assert_array_equal(wbc._A_s, A)
        assert sol.ok
        tau = ctx.M[6:] @ sol.qdd + ctx.h[6:]
        for s in SIDES:
            tau -= ctx.sole_jacobian[s][:, 6:].T @ sol.wrenches[s]
        tau = np.clip(tau, -robot.torque_limit, robot.torque_limit)
        np.testing.assert_allclose(sol.tau, tau, rtol=0, atol=1e-9 * robot.torque_limit.max())
        checked["double" if all(ctx.active.values()) else "single"] += 1
        return sol

    wbc.solve = checking
    for _ in range(900):  # 1.8 s: standing, the weight shift, single supports
        session.step()
    assert checked["single"] > 100 and checked["double"] > 100
