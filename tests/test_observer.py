"""Disturbance observer (eqs. 42–46) and the reference shift (47–49)."""

import math

import numpy as np
import pytest

from dcmviz import GRAVITY
from dcmviz.config import config_from_dict
from dcmviz.dcm import DisturbanceObserver, reference_shift
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
