"""An independent reference for the paper's §II, written from the equations as printed.

Table I and σ (eq. 8) with numpy polynomials; α/β/γ (eqs. 10, 15) as printed but in exact
rational arithmetic (fractions) with exp in 100-digit decimals, so the cancellation of eq. (10)
for short phases (T ≪ b) costs nothing; and the dense 3n matrices of eqs. (13)–(21) inverted
with numpy. The tests compare dcmviz's O(n) implementation against these.
"""

from decimal import Context, Decimal
from fractions import Fraction

import numpy as np
from numpy.polynomial import Polynomial

I3 = np.eye(3)


def table_i_polynomial(T: float, order: int) -> Polynomial:
    """f_φ(t) of Table I as printed, as a polynomial in local time t."""
    tau = Polynomial([0.0, 1.0 / T])
    return {
        0: Polynomial([0.0]),
        1: tau,
        3: tau**2 * (3 - 2 * tau),
        5: tau**3 * (10 - 15 * tau + 6 * tau**2),
    }[order]


def sigma_polynomial(T: float, b: float, order: int) -> Polynomial:
    """σ(t) = Σ_j b^j f^(j)(t), eq. (8), by numpy's polynomial differentiation."""
    P = table_i_polynomial(T, order)
    return sum((b**j * P.deriv(j) for j in range(order + 1)), Polynomial([0.0]))


TABLE_I = {0: (0,), 1: (0, 1), 3: (0, 0, 3, -2), 5: (0, 0, 0, 10, -15, 6)}  # a_k of f(τ), τ = t/T
DIGITS = Context(prec=100)


def sigma_exact(t: Fraction, T: Fraction, b: Fraction, order: int) -> Fraction:
    """σ(t) = Σ_j b^j f^(j)(t), eq. (8), exactly: f^(j)(t) = T^-j Σ_k a_k k!/(k−j)! (t/T)^(k−j)."""
    a = TABLE_I[order]
    total = Fraction(0)
    for j in range(len(a)):
        for k in range(j, len(a)):
            falling = Fraction(np.prod(range(k - j + 1, k + 1), dtype=object) if j else 1)
            total += (b / T) ** j * a[k] * falling * (t / T) ** (k - j)
    return total


def _decimal(x: Fraction) -> Decimal:
    return DIGITS.divide(Decimal(x.numerator), Decimal(x.denominator))


def phase_coefficients_exact(T: float, b: float, order: int, t: float) -> tuple[float, ...]:
    """α_φ(t), β_φ(t), γ_φ(t) of eq. (10) as printed, with the float inputs taken exactly.

    σ is exact (fractions); γ = exp((t − T)/b) and the subtractions of eq. (10) are done with
    100 significant digits, so the result is the correctly rounded float up to ~1e-70 relative
    even when T/b = 1e-4 (eq. 10 then cancels ~27 digits).
    """
    t_, T_, b_ = Fraction(t), Fraction(T), Fraction(b)
    g = DIGITS.exp(_decimal((t_ - T_) / b_))
    s_t, s_T = _decimal(sigma_exact(t_, T_, b_, order)), _decimal(sigma_exact(T_, T_, b_, order))
    alpha = DIGITS.subtract(DIGITS.subtract(1, s_t), DIGITS.multiply(g, DIGITS.subtract(1, s_T)))
    beta = DIGITS.subtract(s_t, DIGITS.multiply(g, s_T))
    return float(alpha), float(beta), float(g)


def phase_coefficients(T: float, b: float, order: int, t: float | np.ndarray = 0.0):
    """α_φ(t), β_φ(t), γ_φ(t) of eq. (10) (eq. 15 at t = 0), by ``phase_coefficients_exact``."""
    if np.ndim(t) == 0:
        return phase_coefficients_exact(float(T), float(b), order, float(t))
    values = np.array([phase_coefficients_exact(float(T), float(b), order, float(x)) for x in t])
    return values[:, 0], values[:, 1], values[:, 2]


def dense_matrices(durations: np.ndarray, b: float, order: int) -> dict[str, np.ndarray]:
    """Eqs. (13), (14), (16), (19), (20), (21) as dense 3n matrices, inverted with numpy."""
    n_phi = len(durations)
    n_wp = n_phi + 1
    A_v_ref_0 = np.kron(np.eye(n_phi, n_wp), I3)  # (13)
    A_v_ref_T = np.kron(np.eye(n_phi, n_wp, k=1), I3)  # (14)
    A_gamma = np.zeros((3 * n_phi, 3 * n_phi))  # (16)
    A_alpha_beta = np.zeros((3 * n_phi, 3 * n_wp))
    for phi, T in enumerate(durations):
        a0, b0, g0 = phase_coefficients(T, b, order)
        A_gamma[3 * phi : 3 * phi + 3, 3 * phi : 3 * phi + 3] = g0 * I3
        A_alpha_beta[3 * phi : 3 * phi + 3, 3 * phi : 3 * phi + 3] = a0 * I3
        A_alpha_beta[3 * phi : 3 * phi + 3, 3 * phi + 3 : 3 * phi + 6] = b0 * I3
    A_BWI = np.kron(np.eye(n_phi, k=1), I3)  # (19)
    A_TC = np.zeros((3 * n_phi, 3 * n_wp))
    A_TC[-3:, -3:] = I3
    eye = np.eye(3 * n_phi)
    A_xi_ref_0 = np.linalg.solve(eye - A_gamma @ A_BWI, A_alpha_beta + A_gamma @ A_TC)  # (20)
    A_xi_ref_T = np.linalg.inv(eye - A_BWI @ A_gamma) @ (A_TC + A_BWI @ A_alpha_beta)  # (21)
    return dict(
        A_v_ref_0=A_v_ref_0, A_v_ref_T=A_v_ref_T, A_xi_ref_0=A_xi_ref_0, A_xi_ref_T=A_xi_ref_T
    )
