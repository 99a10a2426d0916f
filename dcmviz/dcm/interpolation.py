"""Consistent VRP and DCM interpolation of one transition phase (Sec. II-B, Table I, eqs. 5–10, 15).

Time ``t`` is the local time t_φ ∈ [0, T_φ] of a transition phase of duration ``T`` (s); ``b`` is
the DCM time constant (s). Every function broadcasts over numpy arrays of ``t`` and ``T``.

The interpolation function f_φ of Table I is a polynomial in the normalised time τ = t / T,
f(τ) = Σ_k a_k τ^k. Its j-th time derivative is f^(j)(t) = T^-j Σ_k a_{k+j} (k+j)!/k! τ^k, so
σ_φ(t) = Σ_j b^j f^(j)(t) (eq. 8) is a polynomial in τ of the same order.

Numerics. Eq. (10) as printed, β = σ(t) − e^{(t−T)/b} σ_T, subtracts numbers of size (b/T)^n
to get one of size T/b when T ≪ b (order 5, T = 1 ms, b = 0.6 s: 1e16 against 1e-3), and
numbers near 1 to get one near 0 when t is close to T. ``alpha`` and ``beta`` therefore use the
integral form of the solution of eq. (6) that eq. (7) integrates by parts,

    β(t) = (1/b) ∫_t^T e^{−(s−t)/b} f(s) ds,   α(t) = (1/b) ∫_t^T e^{−(s−t)/b} (1 − f(s)) ds,

(so α + β + γ = 1), with the polynomial expanded about t, f(s) = Σ_k f^(k)(t) (s − t)^k / k!:

    β(t) = Σ_k (L/T)^k f_τ^(k)(τ) Q_k(x),   Q_k(x) = x^-k ∫_0^x e^{−u} u^k / k! du,

L = T − t, x = L / b, f_τ^(k) the k-th τ-derivative (for α, 1 − f, written in powers of L/T so
that it is accurate where it is small). The expansion is exact (f is a polynomial), and the
k-th term is at most max|f_τ^(k)| x (L/T)^k / (k+1)!: nothing large cancels for any T/b.
Q_k = P(k+1, x) / x^k is a scaled incomplete gamma function, the only non-polynomial part:
for x ≥ 4 in closed form, (1 − e^{−x} Σ_{j≤k} x^j/j!) / x^k, a subtraction that loses at most
a factor P(1, x)/P(6, x) < 5; below as its power series x e^{−x} Σ_m x^m/(m+k+1)!, positive
terms, cut after 30 (the tail is < 4^30/31! < 2e-16 of the sum). A quadrature rule would only
approximate what this evaluates exactly up to that tail. Measured against exact arithmetic for
T/b from 1e-4 to 50: relative error < 1e-14 for every t ∈ [0, T] (tests/test_interpolation.py).

``Preview`` samples short phases with ``beta_series_coefficients`` and the rest with the
closed form, where ``closed_form_error_bound`` says it is well conditioned.
"""

from __future__ import annotations

import math
import numbers

import numpy as np
from numpy.typing import ArrayLike, NDArray

ORDERS: tuple[int, ...] = (0, 1, 3, 5)
"""Polynomial orders n_poly of Table I."""

# Table I: coefficients a_k of f(τ) = Σ_k a_k τ^k, ascending powers of τ = t / T.
_F_TAU_COEFFICIENTS: dict[int, tuple[float, ...]] = {
    0: (0.0,),
    1: (0.0, 1.0),
    3: (0.0, 0.0, 3.0, -2.0),
    5: (0.0, 0.0, 0.0, 10.0, -15.0, 6.0),
}

# Q_k(x) is summed as a power series below this x, in closed form above (module docstring).
_SERIES_BELOW_X = 4.0
_SERIES_TERMS = 30
_FACTORIALS = np.array([float(math.factorial(k)) for k in range(_SERIES_TERMS + 8)])
# _SERIES[m, k] = 1 / (m + k + 1)!: Q_k(x) = x e^{−x} Σ_m x^m _SERIES[m, k].
_SERIES = 1.0 / _FACTORIALS[np.add.outer(np.arange(_SERIES_TERMS), np.arange(7)) + 1]

# Preview samples the closed form of eq. (10) where ``closed_form_error_bound`` ≤ this.
CLOSED_FORM_ERROR_BOUND = 64.0


def _taylor_shift(a: NDArray, shift: float, scale: float) -> NDArray[np.float64]:
    """Coefficients of p(shift + scale·y) in powers of y, for p = Σ_k a_k x^k (exact for the
    small integers and dyadic numbers used here)."""
    P = np.polynomial.Polynomial(a)
    c = np.asarray(P(np.polynomial.Polynomial([shift, scale])).coef, dtype=np.float64)
    return np.pad(c, (0, len(a) - c.size))


def _derivative_matrix(a: NDArray) -> NDArray[np.float64]:
    """Row k: coefficients of the k-th derivative of Σ_j a_j x^j, padded to len(a)."""
    n = len(a)
    D = np.zeros((n, n))
    c = np.asarray(a, dtype=np.float64)
    for k in range(n):
        D[k, : c.size] = c
        c = c[1:] * np.arange(1, c.size)
    return D


def _integral_form_matrices(order: int) -> tuple[NDArray, NDArray, NDArray]:
    """Rows k = 0 … n: f_τ^(k) in powers of τ; (1 − f)_τ^(k) in powers of y = 1 − τ; and
    max_τ∈[0,1] |f_τ^(k)| (on a grid of 4001 points: a threshold, not a bound to the digit)."""
    a = np.array(_F_TAU_COEFFICIENTS[order])
    F = _derivative_matrix(a)
    one_minus_f_of_y = _taylor_shift(np.concatenate(([1.0 - a[0]], -a[1:])), 1.0, -1.0)
    G = _derivative_matrix(one_minus_f_of_y) * ((-1.0) ** np.arange(a.size))[:, None]
    grid = np.linspace(0.0, 1.0, 4001)
    peaks = np.abs(np.polynomial.polynomial.polyval(grid, F.T)).max(axis=1)
    return F, G, peaks


_INTEGRAL_FORM = {order: _integral_form_matrices(order) for order in _F_TAU_COEFFICIENTS}


def _fixed_fraction_weights(order: int, tau: float) -> NDArray[np.float64]:
    """Rows (1 − f, f): y^k times the k-th τ-derivative at τ, y = 1 − τ (for t = τ T)."""
    F, G, _ = _INTEGRAL_FORM[order]
    y = 1.0 - tau
    y_k = y ** np.arange(order + 1)
    at = np.polynomial.polynomial.polyval
    return np.stack((at(y, G.T) * y_k, at(tau, F.T) * y_k))


# (α_0, β_0) of eq. (15) are Q_k(T/b) @ these rows.
_AT_START = {order: _fixed_fraction_weights(order, 0.0) for order in _F_TAU_COEFFICIENTS}


def _series_matrix(order: int) -> NDArray[np.float64]:
    """K[i, m] = f̃_{m−i} (m−i)! for i ≥ 1, 0 ≤ m − i ≤ n; f̃ = f in powers of s = 2τ − 1.

    28 columns: for h = T/(2b) ≤ 1 the coefficients past 20 are below h^m/m! < 1e-18.
    """
    f_s = _taylor_shift(np.array(_F_TAU_COEFFICIENTS[order]), 0.5, 0.5)
    terms = 28
    K = np.zeros((terms, terms))
    for j, value in enumerate(f_s * _FACTORIALS[: f_s.size]):
        K[np.arange(1, terms - j), np.arange(1 + j, terms)] = value
    return K


_SERIES_MATRIX = {order: _series_matrix(order) for order in _F_TAU_COEFFICIENTS}


# --- validation shared by preview.py and continuity.py ----------------------------------------


def check_order(order: object) -> int:
    """Return ``order`` as an int, or raise ValueError unless it is an n_poly of Table I."""
    if (
        isinstance(order, bool)
        or not isinstance(order, numbers.Integral)
        or int(order) not in ORDERS
    ):
        raise ValueError(
            f"order = {order!r}: the VRP polynomial order must be one of 0, 1, 3, 5 (Table I)"
        )
    return int(order)


def check_b(b: object) -> float:
    """Return the DCM time constant b of eq. (1) as a float; ValueError unless finite and > 0."""
    if isinstance(b, bool) or not isinstance(b, numbers.Real):
        raise ValueError(f"b = {b!r}: the DCM time constant must be a real number > 0 s")
    value = float(b)
    if not math.isfinite(value) or value <= 0.0:
        raise ValueError(f"b = {value!r}: the DCM time constant must be finite and > 0 s")
    return value


def check_durations(durations: ArrayLike, name: str = "durations") -> NDArray[np.float64]:
    """Return the phase durations T_φ (eq. 5) as a read-only (n_phi,) array, all finite > 0 s."""
    try:
        array = np.array(durations, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(
            f"{name} = {durations!r}: must be a 1-D sequence of phase durations in s"
        ) from error
    if array.ndim != 1 or array.size == 0:
        raise ValueError(
            f"{name} has shape {array.shape}: must be a non-empty 1-D sequence (n_phi,) "
            "of phase durations in s"
        )
    bad = np.flatnonzero(~(np.isfinite(array) & (array > 0.0)))
    if bad.size:
        i = int(bad[0])
        raise ValueError(
            f"{name}[{i}] = {float(array[i])!r}: every phase duration must be finite and > 0 s"
        )
    array.flags.writeable = False
    return array


def check_points(points: ArrayLike, name: str, shape: tuple[int | None, int]) -> NDArray:
    """Return VRP points (eqs. 11–14, 25) as a read-only array of ``shape`` (None: any length)."""
    try:
        array = np.array(points, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name} = {points!r}: must be an array of coordinates in m") from error
    if len(shape) == 2 and array.size == 0 and shape[0] in (None, 0):
        array = array.reshape(0, shape[1])
    expected = ", ".join("n" if s is None else str(s) for s in shape)
    expected = f"({expected},)" if len(shape) == 1 else f"({expected})"
    if array.ndim != len(shape) or any(
        s is not None and s != a for s, a in zip(shape, array.shape, strict=True)
    ):
        raise ValueError(
            f"{name} has shape {array.shape}: must have shape {expected} (coordinates in m)"
        )
    bad = np.argwhere(~np.isfinite(array))
    if bad.size:
        index = tuple(int(i) for i in bad[0])
        where = ", ".join(str(i) for i in index)
        raise ValueError(
            f"{name}[{where}] = {float(array[index])!r}: every coordinate must be finite"
        )
    array.flags.writeable = False
    return array


# --- Table I polynomials -----------------------------------------------------------------------


def f_tau_coefficients(order: int, derivative: int = 0) -> NDArray[np.float64]:
    """Coefficients (ascending powers of τ) of d^j f / dτ^j for f of Table I, j = ``derivative``.

    The time derivative is f^(j)(t) = T^-j · (this polynomial)(t / T).
    """
    order = check_order(order)
    a = np.array(_F_TAU_COEFFICIENTS[order])
    for _ in range(derivative):
        a = a[1:] * np.arange(1, a.size) if a.size > 1 else np.zeros(1)
    return a


def sigma_tau_coefficients(T: ArrayLike, b: float, order: int) -> NDArray[np.float64]:
    """Coefficients s_k(T) (ascending powers of τ) of σ(t) = Σ_j b^j f^(j)(t), eq. (8).

    Returns shape ``T.shape + (order + 1,)``: σ(t) = Σ_k s_k τ^k with τ = t / T.
    """
    order = check_order(order)
    b_over_T = b / np.asarray(T, dtype=np.float64)
    # row j of the matrix: the coefficients of d^j f / dτ^j
    return (b_over_T[..., None] ** np.arange(order + 1)) @ _INTEGRAL_FORM[order][0]


def _polyval_tau(coefficients: NDArray, tau: NDArray) -> NDArray:
    """Horner evaluation of Σ_k c_k τ^k, broadcasting c (..., K) against τ (...)."""
    result = np.zeros(np.broadcast_shapes(coefficients.shape[:-1], tau.shape))
    for k in range(coefficients.shape[-1] - 1, -1, -1):
        result = result * tau + coefficients[..., k]
    return result


def _polyval_rows(coefficients: NDArray, x: NDArray) -> NDArray:
    """Horner evaluation of K polynomials (rows of ``coefficients``, (K, J)) at x (..., K)."""
    result = np.zeros(x.shape)
    for j in range(coefficients.shape[1] - 1, -1, -1):
        result *= x
        result += coefficients[:, j]
    return result


def f(t: ArrayLike, T: ArrayLike, order: int, derivative: int = 0) -> NDArray[np.float64]:
    """Interpolation function f_φ(t_φ) of Table I, or its ``derivative``-th time derivative.

    Used in the VRP spline of eq. (5): v_ref(t) = (1 − f(t)) v_ref_0 + f(t) v_ref_T.
    """
    t = np.asarray(t, dtype=np.float64)
    T = np.asarray(T, dtype=np.float64)
    a = f_tau_coefficients(order, derivative)
    return _polyval_tau(a, t / T) / T**derivative


def sigma(
    t: ArrayLike, T: ArrayLike, b: float, order: int, derivative: int = 0
) -> NDArray[np.float64]:
    """σ_φ(t_φ) = Σ_{j=0}^{n_poly} b^j f_φ^(j)(t_φ) of eq. (8), or its ``derivative``-th derivative.

    σ satisfies σ − b σ̇ = f, which makes eq. (7) solve the DCM dynamics (6).
    """
    t = np.asarray(t, dtype=np.float64)
    T = np.asarray(T, dtype=np.float64)
    s = sigma_tau_coefficients(T, b, order)
    for _ in range(derivative):
        s = s[..., 1:] * np.arange(1, s.shape[-1]) if s.shape[-1] > 1 else np.zeros_like(s)
    return _polyval_tau(s, t / T) / T**derivative


def gamma(t: ArrayLike, T: ArrayLike, b: float) -> NDArray[np.float64]:
    """γ_φ(t_φ) = exp((t_φ − T_φ) / b), the weight of ξ_ref_T in eq. (10)."""
    t = np.asarray(t, dtype=np.float64)
    return np.exp((t - np.asarray(T, dtype=np.float64)) / b)


def _scaled_incomplete_gamma(x: NDArray, n: int) -> NDArray[np.float64]:
    """Q_k(x) = x^-k ∫_0^x e^{−u} u^k / k! du for k = 0 … n, shape ``x.shape + (n + 1,)``.

    Q_k(x) = P(k + 1, x) / x^k, P the regularised lower incomplete gamma function. For x ≥ 4
    in closed form, Q_k = (1 − e^{−x} Σ_{j≤k} x^j/j!) / x^k (with 1 − e^{−x} from expm1; the
    subtraction loses at most a factor P(1, x)/P(6, x) < 5); below, the power series
    Q_k = x e^{−x} Σ_m x^m/(m+k+1)!, positive terms, 30 of them (the tail is < 1e-16).
    """
    big = x >= _SERIES_BELOW_X
    n_big = np.count_nonzero(big)
    if n_big == 0:
        return _scaled_incomplete_gamma_series(x, n)
    if n_big == x.size:
        return _scaled_incomplete_gamma_closed(x, n)
    Q = np.empty(x.shape + (n + 1,))
    Q[big] = _scaled_incomplete_gamma_closed(x[big], n)
    Q[~big] = _scaled_incomplete_gamma_series(x[~big], n)
    return Q


def _scaled_incomplete_gamma_closed(x: NDArray, n: int) -> NDArray[np.float64]:
    powers = x[..., None] ** np.arange(n + 1)
    e_k = np.cumsum(powers / _FACTORIALS[: n + 1], axis=-1) - 1.0  # Σ_{1≤j≤k} x^j / j!
    return (-np.expm1(-x)[..., None] - np.exp(-x)[..., None] * e_k) / powers


def _scaled_incomplete_gamma_series(x: NDArray, n: int) -> NDArray[np.float64]:
    series = (x[..., None] ** np.arange(_SERIES_TERMS)) @ _SERIES[:, : n + 1]
    return (x * np.exp(-x))[..., None] * series


def alpha_beta(
    t: ArrayLike, T: ArrayLike, b: float, order: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(α_φ(t_φ), β_φ(t_φ)) of eq. (10), both from the integral form of the module docstring.

    β = Σ_k (L/T)^k f_τ^(k)(τ) Q_k(L/b) and α the same with 1 − f, L = T − t; accurate to
    a few units of the last place for every T/b and t ∈ [0, T] (t outside: |T − t| < 4 b).
    """
    order = check_order(order)
    t, T = np.broadcast_arrays(np.asarray(t, dtype=np.float64), np.asarray(T, dtype=np.float64))
    remaining = T - t
    y = remaining / T  # L / T = 1 − τ
    Q = _scaled_incomplete_gamma(remaining / b, order)
    F, G, _ = _INTEGRAL_FORM[order]
    n = order + 1
    # one Horner pass for f_τ^(k)(τ) (columns 0 … n−1) and (1 − f)_τ^(k) in y (n … 2n−1)
    at = np.repeat(np.stack((y, t / T), axis=-1), n, axis=-1)
    derivatives = _polyval_rows(np.vstack((G, F)), at)
    weighted = (
        derivatives.reshape(at.shape[:-1] + (2, n))
        * (y[..., None] ** np.arange(n) * Q)[..., None, :]
    )
    alpha, beta = np.moveaxis(weighted.sum(axis=-1), -1, 0)
    return alpha, beta


def alpha(t: ArrayLike, T: ArrayLike, b: float, order: int) -> NDArray[np.float64]:
    """α_φ(t_φ) = 1 − σ(t_φ) − exp((t_φ − T_φ)/b) (1 − σ_T), the weight of v_ref_0 in eq. (10).

    Evaluated as (1/b) ∫_t^T e^{−(s−t)/b} (1 − f(s)) ds, the same function without its
    cancellation (module docstring); α + β + γ = 1.
    """
    return alpha_beta(t, T, b, order)[0]


def beta(t: ArrayLike, T: ArrayLike, b: float, order: int) -> NDArray[np.float64]:
    """β_φ(t_φ) = σ(t_φ) − exp((t_φ − T_φ)/b) σ_T, the weight of v_ref_T in eq. (10).

    Evaluated as (1/b) ∫_t^T e^{−(s−t)/b} f(s) ds, the same function without its cancellation
    (module docstring).
    """
    return alpha_beta(t, T, b, order)[1]


def gamma_0(T: ArrayLike, b: float) -> NDArray[np.float64]:
    """γ_0,φ = exp(−T_φ / b), eq. (15)."""
    return np.exp(-np.asarray(T, dtype=np.float64) / b)


def alpha_beta_0(
    T: ArrayLike, b: float, order: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(α_0,φ, β_0,φ) of eq. (15): ``alpha_beta`` at t_φ = 0, Σ_k (1 − f or f)_τ^(k)(0) Q_k(T/b)."""
    Q = _scaled_incomplete_gamma(np.asarray(T, dtype=np.float64) / b, check_order(order))
    alpha_0_beta_0 = Q @ _AT_START[order].T
    return alpha_0_beta_0[..., 0], alpha_0_beta_0[..., 1]


def alpha_0(T: ArrayLike, b: float, order: int) -> NDArray[np.float64]:
    """α_0,φ = 1 − σ_0 − exp(−T_φ/b) (1 − σ_T), eq. (15): ``alpha`` at t_φ = 0."""
    return alpha_beta_0(T, b, order)[0]


def beta_0(T: ArrayLike, b: float, order: int) -> NDArray[np.float64]:
    """β_0,φ = σ_0 − exp(−T_φ/b) σ_T, eq. (15): ``beta`` at t_φ = 0."""
    return alpha_beta_0(T, b, order)[1]


def closed_form_error_bound(T: ArrayLike, b: float, order: int) -> NDArray[np.float64]:
    """Σ_j (b/T)^j max_τ |f_τ^(j)(τ)|: the size of the terms eq. (10) cancels, σ(t) and σ_T
    (eq. 8), relative to the VRP step. The closed form's rounding error is within
    3 (this + 1) 2.2e-16 (measured). ``Preview`` uses the closed form where this is ≤
    ``CLOSED_FORM_ERROR_BOUND`` (order 5: T/b ≥ 1.94; order 3: ≥ 0.64; order 1: ≥ 0.016;
    order 0: always), so its error stays below 4e-14 of |Δv| there.
    """
    peaks = _INTEGRAL_FORM[check_order(order)][2]
    # b/T capped at 1e50: the bound is astronomically above any threshold there anyway
    return _polyval_tau(peaks, np.minimum(b / np.asarray(T, dtype=np.float64), 1e50))


def beta_series_coefficients(T: ArrayLike, b: float, order: int) -> NDArray[np.float64]:
    """Coefficients c_m (one row per T) of β_φ(t_φ) = Σ_m c_m s^m, s = 2 t_φ / T_φ − 1 ∈ [−1, 1].

    β of eq. (10) solves β − b β̇ = f with β(T) = 0 (eq. 6 for v = f, ξ_ref_T = 0). With
    h = T/(2b) and f = Σ_m f̃_m s^m that is (m + 1) c_{m+1} = h (c_m − f̃_m), so
    c_m = (h^m c_0 − Σ_{j<m} f̃_j j! h^{m−j}) / m!, and β(s = 1) = Σ_m c_m = 0 gives c_0. For
    T/b ≲ 4 (``Preview`` uses it below 2) the terms stay of the size of β, nothing cancels, and
    |c_m| falls like h^m/m!: the series is cut where every |c_m| < 1e-17 Σ|c|, at about 20
    columns for T/b = 2. Rounding error: a few 1e-16 of max|β|.
    """
    order = check_order(order)
    T = np.atleast_1d(np.asarray(T, dtype=np.float64))
    K = _SERIES_MATRIX[order]
    H = (T / (2.0 * b))[:, None] ** np.arange(K.shape[0])  # h^m
    E = H / _FACTORIALS[: K.shape[0]]  # the homogeneous solution e^{h s}
    P = -(H @ K) / _FACTORIALS[: K.shape[0]]  # the particular one with c_0 = 0
    c = (-P.sum(axis=1) / E.sum(axis=1))[:, None] * E + P
    magnitude = np.abs(c)
    significant = magnitude > 1e-17 * magnitude.sum(axis=1, keepdims=True)
    last = int(np.flatnonzero(significant.any(axis=0)).max(initial=0))
    return c[:, : last + 1]
