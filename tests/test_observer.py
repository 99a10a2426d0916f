"""Disturbance observer (eqs. 42–46) and the reference shift (47–49)."""

import math

import numpy as np
import pytest

from dcmviz import GRAVITY
from dcmviz.config import config_from_dict
from dcmviz.dcm import DisturbanceObserver, ShiftRate, reference_shift
from dcmviz.session import Session


def test_estimate_follows_a_step_force_with_rate_k_f():
    """A free mass under a known force plus an unknown step force: F̂ ≈ F (1 − e^{−k_F t})."""
    m, k_f, dt = 90.0, 10.0, 1e-3
    obs = DisturbanceObserver(m, k_f)
    velocity = np.array([0.1, 0.0, 0.0])
    obs.reset(velocity)
    f_step = np.array([0.0, 40.0, -15.0])
    known_prev = np.zeros(3)
    worst = 0.0
    for k in range(1, 800):
        t = k * dt
        f_known = np.array([5.0 * math.sin(3 * t), 0.0, 0.0])  # what the controller commands
        # exact momentum balance over the last sample (the force starts at t = 0)
        velocity = velocity + (known_prev + f_step) * dt / m
        estimate = obs.update(velocity, known_prev, dt)
        expected = f_step * (1.0 - math.exp(-k_f * (t - dt)))
        worst = max(worst, np.max(np.abs(estimate - expected)))
        known_prev = f_known
    assert worst < 0.01 * np.linalg.norm(f_step)
    np.testing.assert_allclose(obs.f_hat, f_step, rtol=1e-3, atol=1e-9)


def test_reference_shift_is_minus_b2_over_m_f_hat():
    np.testing.assert_allclose(reference_shift(np.array([0, 90.0, 0]), 90.0, 0.3), [0, -0.09, 0])


@pytest.mark.parametrize("observer", [True, False])
def test_shift_keeps_the_contact_vrp_on_the_nominal_foothold(observer):
    """Under a constant push, the realised contact VRP (eCMP + Δz) stays on the planned VRP with
    the observer (eqs. 47–49); without it the feet push from elsewhere."""
    config = config_from_dict(
        {
            "gait": {"n_steps": 4},
            "control": {"observer": observer, "step_adjustment": False},
            "sim": {"backend": "lip"},
            "pushes": [{"start": 0.0, "duration": 100.0, "force": [0.0, 25.0, 0.0]}],
        }
    )
    s = Session(config)
    s.run(s.plan.duration + 2.0)
    assert not s.fell
    state, cmd = s.last_state, s.last_command
    b, m = config.dcm.b, state.mass
    v_contact = state.com - b * b / m * (
        state.applied_contact_force - m * GRAVITY * np.array([0, 0, 1])
    )
    v_nominal = s.plan.preview.vrp(s.plan.duration)
    offset = np.linalg.norm(v_contact[:2] - v_nominal[:2])
    if observer:
        assert offset < 1e-3
        np.testing.assert_allclose(cmd.f_hat[:2], [0.0, 25.0], atol=0.05)
    else:
        assert offset > 0.02


def test_moment_shift_leans_further_away_from_a_pull_above_the_com():
    """A pull F e_y at height h above the CoM makes τ = h e_z × F e_y = −h F e_x; the centre of
    pressure stays on the foothold only if the CoM moves a further h F / (m g) away from the pull."""
    from dcmviz.dcm import moment_shift

    m, h, force = 90.0, 0.38, 133.0
    tau = np.cross([0.0, 0.0, h], [0.0, force, 0.0])
    np.testing.assert_allclose(
        moment_shift(tau, m, GRAVITY), [0.0, -h * force / (m * GRAVITY), 0.0]
    )


def test_update_before_reset_behaves_as_reset_at_rest():
    """A new observer is usable at once: it starts as if reset with zero CoM velocity."""
    m, k_f, dt = 60.0, 8.0, 1e-3
    fresh, reset = DisturbanceObserver(m, k_f), DisturbanceObserver(m, k_f)
    reset.reset(np.zeros(3))
    rng = np.random.default_rng(0)
    for _ in range(50):
        velocity, f_known = rng.normal(size=3), rng.normal(size=3) * 10
        np.testing.assert_array_equal(
            fresh.update(velocity, f_known, dt), reset.update(velocity, f_known, dt)
        )
    # the first sample after construction: p̂_0 = 0, so F̂_0 = k_F m ẋ_0 (eq. 45)
    obs = DisturbanceObserver(m, k_f)
    np.testing.assert_allclose(obs.update(np.array([0.1, 0, 0]), np.zeros(3), dt), [48.0, 0, 0])


def test_shift_rate_is_a_first_order_low_pass_of_the_shifts_difference():
    """On a shift ramping at r from rest the rate is r (1 − (1 − Δt/τ)^n) after n differences
    (the closed form of the filter), the VRP reference v + s − b ṡ; a constant shift gives 0."""
    dt, tau, b = 2e-3, 0.2, 0.3
    rate = ShiftRate(dt, tau)
    r = np.array([0.01, -0.03, 0.002])  # m/s
    s0 = np.array([0.1, 0.2, 0.0])
    assert np.all(rate.update(s0) == 0.0)  # the first shift is only recorded
    for n in range(1, 401):
        out = rate.update(s0 + r * n * dt)
        np.testing.assert_allclose(out, r * (1.0 - (1.0 - dt / tau) ** n), rtol=1e-9, atol=1e-15)
    v = np.array([1.0, 2.0, 0.8])
    np.testing.assert_allclose(rate.vrp(v, b), v - b * out, rtol=0, atol=1e-15)
    rate.reset()
    for _ in range(5):
        assert np.all(rate.update(s0) == 0.0)


@pytest.mark.parametrize("adjust", [False, True])
def test_a_ramped_load_leaves_only_the_observers_lag_in_the_dcm_error(adjust):
    """Under a force growing at Ḟ the observer lags by Ḟ/k_F (eq. 44) and the shift moves at
    ṡ = −b² Ḟ/m.  With v_ref + s − b ṡ (ShiftRate) the DCM error ė = −k_ξ e + b (F − F̂)/m
    settles at b Ḟ/(m k_ξ k_F); with v_ref + s alone (the paper's constant shift) it settled at
    b Ḟ (1/k_F + b)/(m k_ξ), four times that on Talos's numbers.  Point mass, 10 steps."""
    f_max, ramp = 60.0, 6.0
    config = config_from_dict(
        {
            "gait": {"n_steps": 10},
            "control": {"observer": True, "step_adjustment": adjust},
            "sim": {"backend": "lip"},
            "pushes": [{"start": 0.5, "duration": 30.0, "force": [0.0, f_max, 0.0], "ramp": ramp}],
        }
    )
    s = Session(config)
    errors = []
    while s.t < 6.4:
        cmd = s.step()
        if s.t > 3.0:  # the observer and the filter settled on the ramp (0.5 → 6.5 s)
            errors.append(cmd.xi - cmd.xi_adj)
    assert not s.fell
    e = np.array(errors)
    m, b = s.last_state.mass, config.dcm.b
    k, k_f, rate = config.control.k_xi, config.control.k_f, f_max / ramp
    lag_only = b * rate / (m * k * k_f)
    constant_shift = b * rate * (1.0 / k_f + b) / (m * k)
    assert constant_shift > 3.5 * lag_only
    if not adjust:  # ξ_adj = ξ_ref + s: the error is the controller's alone
        np.testing.assert_allclose(e[:, 1].mean(), lag_only, rtol=0.05)
        assert np.ptp(e[:, 1]) < 0.1 * lag_only
    else:  # the footsteps take part of it (next_step moves them by the error)
        assert 0.5 * lag_only < e[:, 1].mean() < 1.05 * lag_only
    assert np.max(np.abs(e[:, 0])) < 0.05 * constant_shift
