"""Each whole-body task's A (of its term ‖A x - b‖², x = [q̈, w_left, w_right]) checked against
finite differences of the quantity the task controls.

Talos moves along q(t) = q ⊕ (v t + ½ q̈ t²), so v and q̈ are its velocity and acceleration at
t = 0. The rate a task claims, A x (plus the drift it moves into b), must equal the central
difference of its quantity along that motion: the CoM (through m c̈ = Σ f + m g), the centroidal
angular momentum (L̇ = Σ (p_i - c) × f_i + τ_i), the base's and the soles' world angular velocity
(from rotations, log(R(t + h) R(t - h)ᵀ) / 2h), the soles' positions and the joint angles. Where
x holds wrenches, q̈ comes from Pinocchio's forward dynamics (ABA) with the wrenches applied as
external forces on the ankle joints, so neither side uses the sole Jacobian of the other.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pinocchio as pin
import pytest

from dcmviz.robots import SIDES, Robot, load_robot
from dcmviz.sim.wbc import (
    AngularMomentumTask,
    BaseOrientationTask,
    ContactForceTask,
    Context,
    FootTask,
    Kinematics,
    Layout,
    PostureTask,
)
from dcmviz.walker.state import FootTarget, WalkerCommand

H = 1e-4  # s, finite-difference step in time


@pytest.fixture(scope="module")
def robot() -> Robot:
    return load_robot("talos")


def _motion(robot: Robot, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A random-ish (q, v, q̈): base tilted and turned, every joint off its nominal angle."""
    rng = np.random.default_rng(seed)
    q = robot.q_nominal.copy()
    q[:3] += rng.normal(scale=0.1, size=3)
    axis = rng.normal(size=3)
    q[3:7] = pin.Quaternion(pin.exp3(0.5 * axis / np.linalg.norm(axis))).coeffs()  # x y z w
    q[7:] += rng.normal(scale=0.15, size=robot.nu)
    v = rng.normal(scale=0.5, size=robot.nv)
    a = rng.normal(scale=2.0, size=robot.nv)
    return q, v, a


def _along(robot: Robot, q, v, a, t: float) -> tuple[np.ndarray, np.ndarray]:
    """(q(t), v(t)) = (q ⊕ (v t + ½ a t²), v + a t); v(t) is exact up to an even O(t²) term,
    which central differences cancel."""
    return pin.integrate(robot.pin_model, q, v * t + 0.5 * a * t * t), v + a * t


def _rate(f: Callable[[float], np.ndarray]) -> np.ndarray:
    return (f(H) - f(-H)) / (2 * H)


def _second_rate(f: Callable[[float], np.ndarray]) -> np.ndarray:
    return (f(H) - 2 * f(0.0) + f(-H)) / (H * H)


def _omega(rotation: Callable[[float], np.ndarray], t: float) -> np.ndarray:
    """World angular velocity at t from rotations only: log(R(t + h) R(t - h)ᵀ) / 2h."""
    return pin.log3(rotation(t + H) @ rotation(t - H).T) / (2 * H)


def _frame_placement(robot: Robot, q: np.ndarray, frame: int) -> pin.SE3:
    model = robot.pin_model
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[frame].copy()


def _command(robot: Robot, q: np.ndarray, yaw: float = 0.3) -> WalkerCommand:
    feet = {s: _frame_placement(robot, q, robot.sole_frames[s]).translation for s in SIDES}
    zero = np.zeros(3)
    return WalkerCommand(
        t=0.0,
        support={s: False for s in SIDES},
        feet={s: FootTarget(position=feet[s], yaw=yaw) for s in SIDES},
        swing_side="left",
        com_force=zero,
        contact_force=np.array([10.0, -20.0, 900.0]),
        xi=zero,
        xi_ref=zero,
        xi_adj=zero,
        v_ref=zero,
        v_cmd=zero,
        f_hat=zero,
    )


def _context(robot: Robot, q: np.ndarray, v: np.ndarray) -> Context:
    ctx = Kinematics(robot).context(q, v)
    ctx.active = {s: False for s in SIDES}
    return ctx


def _pushed_motion(robot: Robot, seed: int):
    """Random joint torques and sole wrenches [f; τ] (world axes, at the sole origin), and the
    q̈ they cause: ABA with each wrench moved onto its ankle joint as an external force."""
    model = robot.pin_model
    data = model.createData()
    rng = np.random.default_rng(seed)
    q, v, _ = _motion(robot, seed)
    wrenches = {
        s: np.concatenate(
            [rng.normal(scale=20.0, size=3) + [0, 0, 150.0], rng.normal(scale=5.0, size=3)]
        )
        for s in SIDES
    }
    tau = np.zeros(robot.nv)
    tau[6:] = rng.normal(scale=5.0, size=robot.nu)
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    fext = [pin.Force.Zero() for _ in range(model.njoints)]
    for s in SIDES:
        frame = model.frames[robot.sole_frames[s]]
        p = data.oMf[robot.sole_frames[s]].translation
        f, moment = wrenches[s][:3], wrenches[s][3:]
        about_origin = pin.Force(f, moment + np.cross(p, f))  # world axes, about the origin
        fext[frame.parentJoint] += data.oMi[frame.parentJoint].actInv(about_origin)
    a = pin.aba(model, data, q, v, tau, fext).copy()
    return q, v, a, wrenches


def _x(layout: Layout, a: np.ndarray, wrenches: dict[str, np.ndarray]) -> np.ndarray:
    x = np.zeros(layout.nx)
    x[: layout.nv] = a
    for s, wrench in wrenches.items():
        x[layout.wrench[s]] = wrench
    return x


def test_contact_force_task_is_the_com_acceleration_plus_gravity(robot):
    """A x = Σ f_i / m = c̈ - g, c̈ the second difference of Pinocchio's CoM of q(t)."""
    layout = Layout(robot.nv)
    q, v, a, wrenches = _pushed_motion(robot, seed=3)
    task = ContactForceTask(layout, robot.mass, weight=1.0)
    A, _ = task.compute(_context(robot, q, v), _command(robot, q))
    model, data = robot.pin_model, robot.pin_model.createData()

    def com(t: float) -> np.ndarray:
        return pin.centerOfMass(model, data, _along(robot, q, v, a, t)[0]).copy()

    com_acceleration = _second_rate(com)
    assert np.linalg.norm(com_acceleration) > 1.0  # a motion that tests something
    np.testing.assert_allclose(
        A @ _x(layout, a, wrenches), com_acceleration - model.gravity.linear, atol=2e-5
    )  # difference error ≈ 1e-6 m/s²


def test_angular_momentum_task_is_the_centroidal_angular_momentum_rate(robot):
    """m A x = Σ (p_i - c) × f_i + τ_i = L̇, L̇ the central difference of h_G(q(t), v(t))."""
    layout = Layout(robot.nv)
    q, v, a, wrenches = _pushed_motion(robot, seed=4)
    task = AngularMomentumTask(layout, robot.mass, k=5.0, weight=1.0)
    ctx = _context(robot, q, v)
    A, _ = task.compute(ctx, _command(robot, q))
    model, data = robot.pin_model, robot.pin_model.createData()

    def angular_momentum(t: float) -> np.ndarray:
        q_t, v_t = _along(robot, q, v, a, t)
        return pin.computeCentroidalMomentum(model, data, q_t, v_t).angular.copy()

    np.testing.assert_allclose(ctx.angular_momentum, angular_momentum(0.0), atol=1e-9)
    rate = _rate(angular_momentum)
    assert np.linalg.norm(rate) > 10.0
    np.testing.assert_allclose(robot.mass * (A @ _x(layout, a, wrenches)), rate, atol=1e-3)
    # difference error ≈ 5e-5 N m, |L̇| ≈ 100 N m


def test_base_orientation_task_is_the_base_angular_acceleration(robot):
    """A q̈ = ω̇_base (world axes, no drift term), and the ω in b is the base's world angular
    velocity, both from differences of the base rotation along q(t)."""
    layout = Layout(robot.nv)
    q, v, a = _motion(robot, seed=5)
    task = BaseOrientationTask(layout, kp=1.0, kd=1.0, weight=1.0)
    ctx = _context(robot, q, v)
    A, _ = task.compute(ctx, _command(robot, q))
    model, data = robot.pin_model, robot.pin_model.createData()

    def rotation(t: float) -> np.ndarray:
        pin.forwardKinematics(model, data, _along(robot, q, v, a, t)[0])
        return data.oMi[1].rotation.copy()

    np.testing.assert_allclose(ctx.base_rotation, rotation(0.0), atol=1e-12)
    np.testing.assert_allclose(ctx.base_omega, _omega(rotation, 0.0), atol=1e-6)
    angular_acceleration = (_omega(rotation, H) - _omega(rotation, -H)) / (2 * H)
    assert np.linalg.norm(angular_acceleration) > 1.0
    np.testing.assert_allclose(A @ _x(layout, a, {}), angular_acceleration, atol=1e-5)


@pytest.mark.parametrize("side", SIDES)
def test_foot_task_jacobian_and_drift_are_the_sole_velocity_and_acceleration(robot, side):
    """A[:, :nv] v = [ṗ; ω] and A q̈ + J̇ q̇ = [p̈; ω̇] of the sole (world axes), from differences of
    the sole placement along q(t)."""
    layout = Layout(robot.nv)
    q, v, a = _motion(robot, seed=6)
    task = FootTask(side, layout, kp=1.0, kd=1.0, weight=1.0, depth=0.0)
    ctx = _context(robot, q, v)
    A, _ = task.compute(ctx, _command(robot, q))
    frame = robot.sole_frames[side]

    def position(t: float) -> np.ndarray:
        return _frame_placement(robot, _along(robot, q, v, a, t)[0], frame).translation.copy()

    def rotation(t: float) -> np.ndarray:
        return _frame_placement(robot, _along(robot, q, v, a, t)[0], frame).rotation.copy()

    velocity = np.concatenate([_rate(position), _omega(rotation, 0.0)])
    np.testing.assert_allclose(A[:, : layout.nv] @ v, velocity, atol=1e-6)
    np.testing.assert_allclose(ctx.sole_velocity[side], velocity, atol=1e-6)
    acceleration = np.concatenate(
        [_second_rate(position), (_omega(rotation, H) - _omega(rotation, -H)) / (2 * H)]
    )
    assert np.linalg.norm(acceleration) > 1.0
    np.testing.assert_allclose(
        A @ _x(layout, a, {}) + ctx.sole_drift[side], acceleration, atol=1e-5
    )  # difference error ≈ 2e-7


def test_posture_task_is_the_joint_acceleration(robot):
    """A x = θ̈ and the q̇ in b is θ̇, θ = q[7:] along q(t): identity rows on the joint columns."""
    layout = Layout(robot.nv)
    q, v, a = _motion(robot, seed=7)
    task = PostureTask(robot, layout, kp=0.0, kd=1.0, weight=1.0)
    ctx = _context(robot, q, v)
    A, b = task.compute(ctx, _command(robot, q))

    def joints(t: float) -> np.ndarray:
        return _along(robot, q, v, a, t)[0][7:]

    np.testing.assert_allclose(-b, _rate(joints), atol=1e-9)  # kp = 0, kd = 1: b = -θ̇
    np.testing.assert_allclose(A @ _x(layout, a, {}), _second_rate(joints), atol=1e-6)


def test_the_swing_soles_height_weighs_more_as_it_lands(robot):
    """The swinging foot's cost ‖A x − b‖² with ``landing`` = w: its height row (z) is the plain
    task's times sqrt(1 + (w − 1) s(u)), s(u) = 3u² − 2u³ over u = (progress − 0.6)/0.3 clipped
    to [0, 1]; the other rows, and the foot that stands, are the plain task's."""
    import dataclasses

    layout = Layout(robot.nv)
    q, v, _ = _motion(robot, seed=8)
    ctx = _context(robot, q, v)
    plain = FootTask("left", layout, kp=600.0, kd=50.0, weight=10.0, depth=0.0)
    landing = FootTask("left", layout, kp=600.0, kd=50.0, weight=10.0, depth=0.0, landing=10.0)
    standing = FootTask("right", layout, kp=600.0, kd=50.0, weight=10.0, depth=0.0, landing=10.0)
    standing_plain = FootTask("right", layout, kp=600.0, kd=50.0, weight=10.0, depth=0.0)
    for progress in (0.0, 0.3, 0.6, 0.65, 0.75, 0.85, 0.9, 0.97):
        cmd = dataclasses.replace(_command(robot, q), swing_progress=progress)
        A0, b0 = (x.copy() for x in plain.compute(ctx, cmd))
        A1, b1 = (x.copy() for x in landing.compute(ctx, cmd))
        u = min(max((progress - 0.6) / 0.3, 0.0), 1.0)
        scale = math.sqrt(1.0 + 9.0 * (3 * u * u - 2 * u**3))
        rows = [0, 1, 3, 4, 5]
        np.testing.assert_allclose(A1[rows], A0[rows], atol=0)
        np.testing.assert_allclose(b1[rows], b0[rows], atol=0)
        np.testing.assert_allclose(A1[2], scale * A0[2], rtol=1e-12, atol=1e-15)
        assert b1[2] == pytest.approx(scale * b0[2], rel=1e-12, abs=1e-15)
        A2, b2 = (x.copy() for x in standing.compute(ctx, cmd))
        A3, b3 = standing_plain.compute(ctx, cmd)
        np.testing.assert_array_equal(A2, A3)
        np.testing.assert_array_equal(b2, b3)
    assert scale == pytest.approx(math.sqrt(10.0))
