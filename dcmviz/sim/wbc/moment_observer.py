"""Momentum observers of the external wrench: its moment about the CoM (read by the
angular-momentum task) and its force (the floating-base rows)."""

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


class ForceObserver:
    """External force from the linear momentum, the walker's eqs. 42–46 on the backend's own
    measurement: r = k_o (m ẋ(t) − m ẋ(0) − ∫ (F_contact − m g e_z + r) dt), F_contact the
    measured sole contact forces; ṙ = k_o (F_ext − r).  The whole-body QP models the push it
    feels whether or not the walker's observer (and its reference shift) is on."""

    def __init__(self, gain: float, mass: float, gravity: float) -> None:
        self.gain = gain
        self.weight = np.array([0.0, 0.0, -mass * gravity])
        self.mass = mass
        self.reset(np.zeros(3))

    def reset(self, com_velocity: np.ndarray) -> None:
        self.p0 = self.mass * np.array(com_velocity, dtype=float)
        self.integral = np.zeros(3)
        self.estimate = np.zeros(3)

    def update(self, com_velocity: np.ndarray, contact_force: np.ndarray, dt: float) -> None:
        self.integral += (contact_force + self.weight + self.estimate) * dt
        self.estimate = self.gain * (self.mass * com_velocity - self.p0 - self.integral)
