"""Table I and eqs. (5)–(10), (15) against independent computations."""

import numpy as np
import pytest
from dcm_reference import sigma_polynomial, table_i_polynomial
from scipy.integrate import solve_ivp

from dcmviz.dcm import alpha, alpha_0, beta, beta_0, f, gamma, gamma_0, sigma

ORDERS = (0, 1, 3, 5)


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("T", [0.1, 0.7, 2.3])
def test_f_and_derivatives_match_table_i(order: int, T: float) -> None:
    t = np.linspace(-0.2 * T, 1.2 * T, 41)
    P = table_i_polynomial(T, order)
    for j in range(order + 2):
        np.testing.assert_allclose(f(t, T, order, j), P.deriv(j)(t), rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("order", ORDERS)
def test_table_i_boundary_conditions(order: int) -> None:
    T = 0.8
    if order == 0:
        assert np.all(f(np.linspace(0, T, 9), T, 0) == 0.0)
        return
    assert f(0.0, T, order) == pytest.approx(0.0, abs=1e-15)
    assert f(T, T, order) == pytest.approx(1.0, abs=1e-14)
    # v̇ (order 3) and v̈ (order 5) vanish at both ends
    for j in range(1, (order + 1) // 2):
        assert f(0.0, T, order, j) == pytest.approx(0.0, abs=1e-12)
        assert f(T, T, order, j) == pytest.approx(0.0, abs=1e-9)
    # the next derivative does not: the conditions listed are exactly Table I's
    j = (order + 1) // 2
    assert abs(f(0.0, T, order, j)) > 1e-3 or abs(f(T, T, order, j)) > 1e-3


@pytest.mark.parametrize("order", ORDERS)
def test_derivatives_match_finite_differences(order: int) -> None:
    T, b, h = 0.6, 0.3, 1e-6
    t = np.linspace(0.05, 0.55, 11)
    for j in range(order):
        fd = (f(t + h, T, order, j) - f(t - h, T, order, j)) / (2 * h)
        np.testing.assert_allclose(f(t, T, order, j + 1), fd, rtol=1e-6, atol=1e-5)
    fd = (sigma(t + h, T, b, order) - sigma(t - h, T, b, order)) / (2 * h)
    np.testing.assert_allclose(sigma(t, T, b, order, 1), fd, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("T", [0.2, 0.9])
def test_sigma_is_eq_8(order: int, T: float) -> None:
    b = 0.31
    t = np.linspace(0, T, 17)
    np.testing.assert_allclose(
        sigma(t, T, b, order), sigma_polynomial(T, b, order)(t), rtol=1e-12, atol=1e-12
    )
    # σ − b σ̇ = f, the identity that makes eq. (7) solve eq. (6)
    np.testing.assert_allclose(
        sigma(t, T, b, order) - b * sigma(t, T, b, order, 1), f(t, T, order), atol=1e-10
    )


@pytest.mark.parametrize("order", ORDERS)
def test_alpha_beta_gamma_solve_the_dcm_ode(order: int) -> None:
    """Eq. (10) against backward integration of eq. (6) from ξ_ref_T, one phase, 3-D."""
    rng = np.random.default_rng(order)
    T, b = 0.7, 0.28
    v0, vT, xi_T = rng.uniform(-1, 1, (3, 3))
    P = table_i_polynomial(T, order)

    def rhs(t: float, xi: np.ndarray) -> np.ndarray:
        v = (1 - P(t)) * v0 + P(t) * vT  # eq. (5)
        return (xi - v) / b  # eq. (6)

    t = np.linspace(0, T, 15)
    solution = solve_ivp(rhs, (T, 0.0), xi_T, t_eval=t[::-1], rtol=1e-10, atol=1e-12)
    expected = solution.y.T[::-1]
    a, be, g = alpha(t, T, b, order), beta(t, T, b, order), gamma(t, T, b)
    xi = a[:, None] * v0 + be[:, None] * vT + g[:, None] * xi_T
    np.testing.assert_allclose(xi, expected, atol=1e-8)
    # eq. (15) is eq. (10) at t = 0
    assert alpha_0(T, b, order) == pytest.approx(a[0], abs=1e-12)
    assert beta_0(T, b, order) == pytest.approx(be[0], abs=1e-12)
    assert gamma_0(T, b) == pytest.approx(np.exp(-T / b), rel=1e-15)
    # eq. (15) with the paper's σ_0, σ_T
    s = sigma_polynomial(T, b, order)
    assert alpha_0(T, b, order) == pytest.approx(1 - s(0) - np.exp(-T / b) * (1 - s(T)), abs=1e-12)
    assert beta_0(T, b, order) == pytest.approx(s(0) - np.exp(-T / b) * s(T), abs=1e-12)


def test_vectorised_over_durations() -> None:
    T = np.array([0.2, 0.5, 1.0])
    np.testing.assert_allclose(
        alpha_0(T, 0.3, 5), [float(alpha_0(x, 0.3, 5)) for x in T], rtol=1e-12
    )
    t = np.array([0.1, 0.2, 0.3])
    np.testing.assert_allclose(
        beta(t, T, 0.3, 3), [float(beta(a, x, 0.3, 3)) for a, x in zip(t, T, strict=True)]
    )


@pytest.mark.parametrize("order", [2, 4, -1, 1.0, "5", True, None])
def test_unknown_order_raises(order: object) -> None:
    with pytest.raises(ValueError, match=r"order = .*0, 1, 3, 5"):
        f(0.1, 1.0, order)  # type: ignore[arg-type]
