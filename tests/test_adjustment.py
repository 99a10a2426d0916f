"""Step adjustment and DCM adaptation (eqs. 27–35) against dense matrices and re-built previews."""

import math

import numpy as np
import pytest

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


def dense_A_xi_ref_T(p: Preview) -> np.ndarray:
    """Eq. (21) built and inverted densely (independent of the O(n) recursion)."""
    T, b, n = p.durations, p.b, p.n_phases
    n_wp = n + 1
    from dcmviz.dcm import alpha_0, beta_0, gamma_0

    a0, b0, g0 = alpha_0(T, b, p.order), beta_0(T, b, p.order), gamma_0(T, b)
    I3 = np.eye(3)
    A_gamma = np.kron(np.diag(g0), I3)
    A_ab = np.zeros((3 * n, 3 * n_wp))
    for i in range(n):
        A_ab[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = a0[i] * I3
        A_ab[3 * i : 3 * i + 3, 3 * i + 3 : 3 * i + 6] = b0[i] * I3
    A_bwi = np.kron(np.eye(n, k=1), I3)
    A_tc = np.zeros((3 * n, 3 * n_wp))
    A_tc[-3:, -3:] = I3
    return np.linalg.inv(np.eye(3 * n) - A_bwi @ A_gamma) @ (A_tc + A_bwi @ A_ab)


def dense_d(p: Preview, t: float, S: np.ndarray, phi_fa: int, A_T: np.ndarray) -> np.ndarray:
    """A_xi_ref_φ(t) S_adj A_adj from eqs. (23), (32), (35) with dense 3-D matrices."""
    from dcmviz.dcm import alpha, beta, gamma

    phi, t_phi = p.phase_at(t)
    T = p.durations[phi]
    n_wp = p.n_phases + 1
    I3 = np.eye(3)
    A_v0 = np.zeros((3, 3 * n_wp))
    A_v0[:, 3 * phi : 3 * phi + 3] = I3
    A_vT = np.zeros((3, 3 * n_wp))
    A_vT[:, 3 * phi + 3 : 3 * phi + 6] = I3
    A_phi = (
        alpha(t_phi, T, p.b, p.order) * A_v0
        + beta(t_phi, T, p.b, p.order) * A_vT
        + gamma(t_phi, T, p.b) * A_T[3 * phi : 3 * phi + 3]
    )
    A_0 = p.A_xi_ref_0  # eq. (20)
    A_adj = np.linalg.inv(A_0[3 * phi_fa : 3 * phi_fa + 3] @ S)  # eq. (32)
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
    A_T = dense_A_xi_ref_T(plan.preview)
    times = np.linspace(t_lift, t_fa, 15)
    d = [adaptation_factor(plan.preview, t, phi_fa, plan.selection(k)) for t in times]
    for t, value in zip(times, d, strict=True):
        D = dense_d(plan.preview, t, S3, phi_fa, A_T)
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
