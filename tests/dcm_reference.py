"""An independent reference for the paper's §II, written from the equations as printed.

Table I, σ (eq. 8), α/β/γ (eqs. 10, 15) with numpy polynomials, and the dense 3n matrices of
eqs. (13)–(21) inverted with numpy: the tests compare dcmviz's O(n) implementation against these.
"""

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


def phase_coefficients(T: float, b: float, order: int, t: float | np.ndarray = 0.0):
    """α_φ(t), β_φ(t), γ_φ(t) of eq. (10) from numpy polynomials (eq. 15 at t = 0)."""
    s = sigma_polynomial(T, b, order)
    g = np.exp((t - T) / b)
    return 1 - s(t) - g * (1 - s(T)), s(t) - g * s(T), g


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
