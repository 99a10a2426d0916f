"""Table I and eqs. (5)–(10), (15) against independent computations."""

import numpy as np
import pytest
from dcm_reference import phase_coefficients_exact, sigma_polynomial, table_i_polynomial
from scipy.integrate import quad, solve_ivp

from dcmviz.dcm import alpha, alpha_0, beta, beta_0, f, gamma, gamma_0, sigma
from dcmviz.dcm.interpolation import (
    CLOSED_FORM_ERROR_BOUND,
    beta_series_coefficients,
    closed_form_error_bound,
)

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


# --- numerics: the integral form for every T/b (issue 9) --------------------------------------

T_OVER_B = np.geomspace(1e-4, 50.0, 23)
FRACTIONS = np.array([0.0, 1e-9, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99, 1 - 1e-6, 1.0])


def relative_error(value: np.ndarray, exact: np.ndarray) -> np.ndarray:
    return np.abs(value - exact) / np.where(exact == 0.0, 1.0, np.abs(exact))


@pytest.mark.parametrize("order", ORDERS)
def test_alpha_beta_match_exact_arithmetic_for_every_t_over_b(order: int) -> None:
    """α, β of eq. (10) against eq. (10) as printed in exact rationals + 100-digit exp, for
    T/b from 1e-4 to 50 and t from 0 to T: relative error ≤ 1e-12 (reached: < 1e-14)."""
    b = 0.6
    worst = 0.0
    for T in T_OVER_B * b:
        t = FRACTIONS * T
        exact = np.array([phase_coefficients_exact(T, b, order, x) for x in t])
        worst = max(
            worst,
            relative_error(alpha(t, T, b, order), exact[:, 0]).max(),
            relative_error(beta(t, T, b, order), exact[:, 1]).max(),
            relative_error(gamma(t, T, b), exact[:, 2]).max(),
            relative_error(alpha_0(T, b, order), exact[0, 0]),
            relative_error(beta_0(T, b, order), exact[0, 1]),
        )
    assert worst <= 1e-12
    assert worst < 5e-14  # what it reaches: a few units of the last place


def test_short_phase_weights_do_not_vanish() -> None:
    """The case of issue 9: T = 1 ms, b = 0.6 s, order 5 gave α_0 = β_0 = 0 (eq. 15 cancels
    1e16-sized terms). For z = T/b ≪ 1, (1/b) ∫_0^T e^{−s/b} f(s/T) ds = z/2 − 5z²/14 + O(z³)
    and α_0 = z/2 − z²/7 + O(z³) (order 5: ∫ τ f dτ = 5/14)."""
    T, b = 1e-3, 0.6
    z = T / b
    assert beta_0(T, b, 5) == pytest.approx(z / 2 - 5 * z**2 / 14, rel=1e-5)
    assert alpha_0(T, b, 5) == pytest.approx(z / 2 - z**2 / 7, rel=1e-5)
    assert alpha_0(T, b, 5) + beta_0(T, b, 5) == pytest.approx(-np.expm1(-T / b), rel=1e-15)


@pytest.mark.parametrize("order", [1, 3, 5])
def test_integral_form_by_quadrature(order: int) -> None:
    """The identity used: β(t) = (1/b) ∫_t^T e^{−(s−t)/b} f(s) ds and α the same with 1 − f
    (adaptive quadrature, independent of both eq. 10 and the code's series)."""
    b = 0.3

    def integral(v, t: float, T: float) -> float:
        return quad(lambda s: np.exp(-(s - t) / b) / b * v(s), t, T, epsabs=0, epsrel=1e-13)[0]

    for T in (1e-3, 0.05, 0.7, 6.0):
        P = table_i_polynomial(T, order)
        for t in (0.0, 0.4 * T, 0.95 * T):
            assert beta(t, T, b, order) == pytest.approx(integral(P, t, T), rel=1e-12)
            assert alpha(t, T, b, order) == pytest.approx(integral(1 - P, t, T), rel=1e-12)


@pytest.mark.parametrize("order", ORDERS)
def test_alpha_beta_gamma_sum_to_one(order: int) -> None:
    b = 0.45
    T = np.repeat(T_OVER_B * b, FRACTIONS.size)
    t = np.tile(FRACTIONS, T_OVER_B.size) * T
    total = alpha(t, T, b, order) + beta(t, T, b, order) + gamma(t, T, b)
    np.testing.assert_allclose(total, 1.0, rtol=0, atol=4e-15)


@pytest.mark.parametrize("order", ORDERS)
def test_beta_series_matches_exact_arithmetic(order: int) -> None:
    """The series in s = 2t/T − 1 that Preview samples in short phases (T/b < 2)."""
    b = 0.6
    T = np.geomspace(1e-4, 2.0, 9) * b
    c = beta_series_coefficients(T, b, order)
    for row, T_phi in zip(c, T, strict=True):
        t = FRACTIONS * T_phi
        value = np.polynomial.polynomial.polyval(2 * t / T_phi - 1, row)
        exact = np.array([phase_coefficients_exact(T_phi, b, order, x)[1] for x in t])
        np.testing.assert_allclose(value, exact, rtol=0, atol=1e-15 * max(exact.max(), 1e-300))


@pytest.mark.parametrize("order", [1, 3, 5])
def test_closed_form_error_bound_bounds_the_closed_form(order: int) -> None:
    """Where ``closed_form_error_bound`` ≤ 64 (the phases Preview samples in closed form),
    eq. (10) as printed in floats is within 3 (bound + 1) 2.2e-16 of the exact value."""
    b = 0.3
    for T in np.linspace(0.01, 8.0, 60) * b:
        bound = closed_form_error_bound(T, b, order)
        if bound > CLOSED_FORM_ERROR_BOUND:
            continue
        t = np.linspace(0.0, T, 21)
        closed = sigma(t, T, b, order) - gamma(t, T, b) * sigma(T, T, b, order)
        exact = np.array([phase_coefficients_exact(T, b, order, x)[1] for x in t])
        assert np.abs(closed - exact).max() <= 3 * (bound + 1) * 2.23e-16
