"""DCM controllers, Δz_vrp and the VRP → CoM force map (eqs. 1, 4, 24, 40, 41)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dcmviz import GRAVITY


def vrp_height(b: float) -> float:
    """Δz_vrp = g b² (m): the height of the VRP above the eCMP, and the CoM height of a robot
    standing with this b (the definition of b below eq. 1)."""
    return GRAVITY * b * b


def dcm(com: NDArray, com_velocity: NDArray, b: float) -> NDArray:
    """ξ = x + b ẋ (eq. 1)."""
    return np.asarray(com, dtype=float) + b * np.asarray(com_velocity, dtype=float)


def vrp_tracking(v_ref: NDArray, xi: NDArray, xi_ref: NDArray, k_xi: float, b: float) -> NDArray:
    """v = v_ref + (I + K_ξ b)(ξ − ξ_ref) with K_ξ = k_xi I (eq. 24).

    With ``xi_ref`` replaced by the adjusted reference ξ_adj this is eq. (41).
    """
    return np.asarray(v_ref, float) + (1.0 + k_xi * b) * (np.asarray(xi, float) - xi_ref)


def vrp_adjusted(
    v_ref: NDArray, xi: NDArray, xi_ref: NDArray, d: float, k_xi: float, b: float
) -> NDArray:
    """v = v_ref + (1 − d_φ(t))(I + K_ξ b) ξ̃ (eq. 40), ξ̃ = ξ − ξ_ref; equal to (41) when the
    adjustment is not clipped."""
    return np.asarray(v_ref, float) + (1.0 - d) * (1.0 + k_xi * b) * (
        np.asarray(xi, float) - xi_ref
    )


def com_force(com: NDArray, vrp: NDArray, mass: float, b: float) -> NDArray:
    """Total force on the CoM encoded by the VRP: F = m / b² (x − v) (eq. 4)."""
    return mass / (b * b) * (np.asarray(com, float) - np.asarray(vrp, float))


def vrp_from_force(com: NDArray, force: NDArray, mass: float, b: float) -> NDArray:
    """Inverse of eq. (4): v = x − b² F / m."""
    return np.asarray(com, float) - (b * b / mass) * np.asarray(force, float)
