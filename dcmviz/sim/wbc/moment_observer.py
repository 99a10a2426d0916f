"""Estimate of the external moment about the CoM, read by the angular-momentum task."""

from __future__ import annotations

import numpy as np


class MomentObserver:
    """External moment about the CoM from the centroidal angular momentum (the angular twin of
    the walker's eqs. 42–46): r = k_o (L(t) - L(0) - ∫ (τ_contact + r) dt), τ_contact the measured
    contact moments about the CoM; ṙ = k_o (τ_ext - r), a first-order estimate of τ_ext."""

    def __init__(self, gain: float) -> None:
        self.gain = gain
        self.reset(np.zeros(3))

    def reset(self, angular_momentum: np.ndarray) -> None:
        self.L0 = np.array(angular_momentum, dtype=float)
        self.integral = np.zeros(3)
        self.estimate = np.zeros(3)

    def update(self, angular_momentum: np.ndarray, contact_moment: np.ndarray, dt: float) -> None:
        self.integral += (contact_moment + self.estimate) * dt
        self.estimate = self.gain * (angular_momentum - self.L0 - self.integral)
