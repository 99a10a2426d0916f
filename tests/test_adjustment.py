"""Step adjustment and DCM adaptation (eqs. 27–35) against dense matrices and re-built previews."""

import math

import numpy as np
import pytest
from dcm_reference import dense_matrices, phase_coefficients

from dcmviz.config import Config
from dcmviz.dcm import (
    Preview,
    adaptation_factor,
    adjusted_waypoints,
    adjustment_gain,
    dcm_adjustment,
    step_adjustment,
)
from dcmviz.gait import plan_from_config


def dense_d(p: Preview, t: float, S: np.ndarray, phi_fa: int, dense: dict) -> np.ndarray:
    """A_xi_ref_φ(t) S_adj A_adj from eqs. (23), (32), (35) with the dense reference matrices."""
    phi, t_phi = p.phase_at(t)
    rows = slice(3 * phi, 3 * phi + 3)
    a, b_, g = phase_coefficients(p.durations[phi], p.b, p.order, t_phi)
    A_phi = (
        a * dense["A_v_ref_0"][rows] + b_ * dense["A_v_ref_T"][rows] + g * dense["A_xi_ref_T"][rows]
    )  # eq. (23)
    A_adj = np.linalg.inv(dense["A_xi_ref_0"][3 * phi_fa : 3 * phi_fa + 3] @ S)  # eq. (32)
    return A_phi @ S @ A_adj  # eq. (35)


@pytest.mark.parametrize("order", [1, 3, 5])
def test_d_rises_from_exp_minus_tss_over_b_to_one(order):
    config = Config().replace(dcm={"order": order, "b": 0.3})
    plan = plan_from_config(config)
    k = 3
    S3 = np.kron(plan.selection(k)[:, None], np.eye(3))  # S_adj of eq. (29), (3 n_wp, 3)
    phi_fa = plan.first_affected_phase(k)
    t_fa = plan.phase_start(phi_fa)
    t_lift, t_touch = plan.swing_window(k)
    assert t_touch == pytest.approx(t_fa)  # the adjustment instant is the touchdown
    dense = dense_matrices(plan.durations, plan.b, plan.order)
    times = np.linspace(t_lift, t_fa, 15)
    d = [adaptation_factor(plan.preview, t, phi_fa, plan.selection(k)) for t in times]
    for t, value in zip(times, d, strict=True):
        D = dense_d(plan.preview, t, S3, phi_fa, dense)
        np.testing.assert_allclose(D, value * np.eye(3), atol=1e-9)  # d_φ(t) I, eq. (35)
        # during single support the VRP stands still, so d = exp((t − t_touch)/b) exactly
        assert value == pytest.approx(math.exp((t - t_fa) / 0.3), rel=1e-9)
    assert d[0] == pytest.approx(math.exp(-0.7 / 0.3), rel=1e-9)
    assert d[-1] == pytest.approx(1.0, abs=1e-12)
    assert np.all(np.diff(d) > 0)


def test_adjustment_cancels_the_error_at_the_adjustment_instant():
    """Eq. (31): with Δv_adj from eq. (32), the adjusted plan's DCM at t_fa is ξ_ref + ξ̃."""
    plan = plan_from_config(Config())
    k = 4
    s = plan.selection(k)
    phi_fa = plan.first_affected_phase(k)
    t = plan.swing_window(k)[0] + 0.25
    xi_error = np.array([0.02, -0.035, 0.0])
    dv = step_adjustment(plan.preview, phi_fa, s, xi_error)
    assert dv[2] == 0.0
    rebuilt = Preview(adjusted_waypoints(plan.waypoints, s, dv), plan.durations, 0.3, 5)
    # ξ_adj(t) = ξ_ref(t) + d ξ̃ (eqs. 33–35) is the DCM of the rebuilt plan (eq. 27)
    xi_adj = plan.preview.dcm(t) + dcm_adjustment(plan.preview, t, s, dv)
    np.testing.assert_allclose(rebuilt.dcm(t), xi_adj, atol=1e-12)
    t_fa = plan.phase_start(phi_fa)
    np.testing.assert_allclose(
        rebuilt.xi_ref_0[phi_fa] - plan.preview.xi_ref_0[phi_fa], xi_error, atol=1e-12
    )
    np.testing.assert_allclose(rebuilt.dcm(t_fa), plan.preview.dcm(t_fa) + xi_error, atol=1e-12)
    # at the instant of adjustment the adapted reference is the (persisting) measured DCM
    measured = plan.preview.dcm(t_fa) + xi_error
    np.testing.assert_allclose(
        plan.preview.dcm(t_fa) + dcm_adjustment(plan.preview, t_fa, s, dv), measured, atol=1e-12
    )
    # the gain is the scalar inverse of 3row(A_xi_ref_0, φ_fa) S_adj
    S3 = np.kron(s[:, None], np.eye(3))
    block = plan.preview.A_xi_ref_0[3 * phi_fa : 3 * phi_fa + 3] @ S3
    np.testing.assert_allclose(
        np.linalg.inv(block), adjustment_gain(plan.preview, phi_fa, s) * np.eye(3), atol=1e-9
    )
