"""Consistent VRP and DCM interpolation of one transition phase (Sec. II-B, Table I, eqs. 5–10, 15).

Time ``t`` is the local time t_φ ∈ [0, T_φ] of a transition phase of duration ``T`` (s); ``b`` is
the DCM time constant (s). Every function broadcasts over numpy arrays of ``t`` and ``T``.

The interpolation function f_φ of Table I is a polynomial in the normalised time τ = t / T,
f(τ) = Σ_k a_k τ^k. Its j-th time derivative is f^(j)(t) = T^-j Σ_k a_{k+j} (k+j)!/k! τ^k, so
σ_φ(t) = Σ_j b^j f^(j)(t) (eq. 8) is a polynomial in τ of the same order.
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
    T = np.asarray(T, dtype=np.float64)
    b_over_T = b / T
    s = np.zeros(T.shape + (order + 1,))
    for j in range(order + 1):
        a_j = f_tau_coefficients(order, j)
        s[..., : a_j.size] += (b_over_T**j)[..., None] * a_j
    return s


def _polyval_tau(coefficients: NDArray, tau: NDArray) -> NDArray:
    """Horner evaluation of Σ_k c_k τ^k, broadcasting c (..., K) against τ (...)."""
    result = np.zeros(np.broadcast_shapes(coefficients.shape[:-1], tau.shape))
    for k in range(coefficients.shape[-1] - 1, -1, -1):
        result = result * tau + coefficients[..., k]
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


def alpha(t: ArrayLike, T: ArrayLike, b: float, order: int) -> NDArray[np.float64]:
    """α_φ(t_φ) = 1 − σ(t_φ) − exp((t_φ − T_φ)/b) (1 − σ_T), the weight of v_ref_0 in eq. (10)."""
    sigma_T = sigma(T, T, b, order)
    return 1.0 - sigma(t, T, b, order) - gamma(t, T, b) * (1.0 - sigma_T)


def beta(t: ArrayLike, T: ArrayLike, b: float, order: int) -> NDArray[np.float64]:
    """β_φ(t_φ) = σ(t_φ) − exp((t_φ − T_φ)/b) σ_T, the weight of v_ref_T in eq. (10)."""
    sigma_T = sigma(T, T, b, order)
    return sigma(t, T, b, order) - gamma(t, T, b) * sigma_T


def gamma_0(T: ArrayLike, b: float) -> NDArray[np.float64]:
    """γ_0,φ = exp(−T_φ / b), eq. (15)."""
    return np.exp(-np.asarray(T, dtype=np.float64) / b)


def alpha_0(T: ArrayLike, b: float, order: int) -> NDArray[np.float64]:
    """α_0,φ = 1 − σ_0 − exp(−T_φ/b) (1 − σ_T), eq. (15)."""
    s = sigma_tau_coefficients(T, b, order)
    sigma_0, sigma_T = s[..., 0], s.sum(axis=-1)
    return 1.0 - sigma_0 - gamma_0(T, b) * (1.0 - sigma_T)


def beta_0(T: ArrayLike, b: float, order: int) -> NDArray[np.float64]:
    """β_0,φ = σ_0 − exp(−T_φ/b) σ_T, eq. (15)."""
    s = sigma_tau_coefficients(T, b, order)
    sigma_0, sigma_T = s[..., 0], s.sum(axis=-1)
    return sigma_0 - gamma_0(T, b) * sigma_T
