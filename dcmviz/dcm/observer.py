"""Momentum-based disturbance observer and reference shift (Sec. III-C, eqs. 42–49)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dcmviz import GRAVITY


class DisturbanceObserver:
    """Discrete observer of the external force (eqs. 45, 46); continuous form eqs. (42)–(44).

    F̂_k = k_F (m ẋ_k − p̂_k)                (45)
    p̂_{k+1} = p̂_k + (F_known,k + F̂_k) Δt   (46)

    so F̂ follows the true perturbation with first-order dynamics of rate k_F (eq. 44).
    ``F_known`` is every force on the CoM that the controller knows: the commanded contact force
    plus gravity.

    A new observer starts as if ``reset`` at rest (p̂ = 0, F̂ = 0), so ``update`` works at once;
    call ``reset`` with the measured CoM velocity when the robot is not at rest.
    """

    def __init__(self, mass: float, k_f: float) -> None:
        if not mass > 0.0:
            raise ValueError(f"mass = {mass}: must be > 0 kg")
        if not k_f > 0.0:
            raise ValueError(f"k_f = {k_f}: must be > 0 1/s")
        self.mass = float(mass)
        self.k_f = float(k_f)
        self.reset(np.zeros(3))

    def reset(self, com_velocity: NDArray) -> None:
        """p̂_0 = m ẋ(0) (eq. 42 at initialisation), F̂ = 0."""
        self._p_hat = (self.mass * np.asarray(com_velocity, dtype=float)).tolist()
        self.f_hat = np.zeros(3)
        self._f_hat = [0.0, 0.0, 0.0]
        self._started = False

    @property
    def p_hat(self) -> NDArray:
        """p̂, the estimated momentum (N·s) of eq. (46)."""
        return np.array(self._p_hat)

    def update(self, com_velocity: NDArray, f_known: NDArray, dt: float) -> NDArray:
        """One sample k: p̂_k from eq. (46), then F̂_k from eq. (45); returns F̂_k (N).

        ``f_known`` is the known force over the last sample (k−1 → k), so eq. (46) is applied
        when that force is known (the realised force, not only the one asked for).  Per
        component in floats (3-vectors, every tick: numpy's per-call overhead would be most of
        the cost), the same operations as on arrays.
        """
        p = self._p_hat
        if self._started:
            f = self._f_hat
            fx, fy, fz = np.asarray(f_known, float).tolist()
            p = self._p_hat = [p[0] + (fx + f[0]) * dt, p[1] + (fy + f[1]) * dt,
                               p[2] + (fz + f[2]) * dt]  # fmt: skip
        self._started = True
        k_f, m = self.k_f, self.mass
        vx, vy, vz = np.asarray(com_velocity, float).tolist()
        f = self._f_hat = [k_f * (m * vx - p[0]), k_f * (m * vy - p[1]), k_f * (m * vz - p[2])]
        self.f_hat = np.array(f)
        return self.f_hat


def reference_shift(f_hat: NDArray, mass: float, b: float) -> NDArray:
    """Offset −b²/m F̂ added to v_ref, ξ_ref and ξ_adj (eqs. 47–49)."""
    return -(b * b / mass) * np.asarray(f_hat, dtype=float)


def moment_shift(tau_hat: NDArray, mass: float, gravity: float = GRAVITY) -> NDArray:
    """Extra reference offset (−τ̂_y, τ̂_x, 0)/(m g) for an external moment τ̂ about the CoM.

    Not in the paper, whose shift (47)–(49) assumes the force acts at the CoM: a push above the
    CoM (a pull on the torso) also turns the robot.  Cancelling that moment needs the centre of
    pressure (τ̂_y, −τ̂_x)/(m g) away from the force line through the CoM; shifting the VRP and DCM
    references the other way keeps the centre of pressure on the nominal foothold, just as
    eqs. (47)–(49) keep the eCMP there.
    """
    tau = np.asarray(tau_hat, dtype=float)
    return np.array([-tau[1], tau[0], 0.0]) / (mass * gravity)


SHIFT_RATE_TAU_S = 0.2  # s, low-pass of the shift's rate (F̂ carries impacts and QP transients)


class ShiftRate:
    """ṡ, the rate of the reference shift s(t) (eqs. 47–49 with ``moment_shift``), low-passed.

    Not in the paper, which shifts every reference by the same s and so assumes s constant.  A
    shifted pair ξ_ref + s, v_ref + s is a DCM and its VRP (ξ̇ = (ξ − v)/b, eq. 5) only while
    ṡ = 0: under a load that grows (the tug of war's 6 s ramp), the DCM controller (eq. 24)
    keeps a steady error e = −ṡ/k_ξ + b (F − F̂)/(m k_ξ), both parts towards the load (the
    first 7 mm of the point mass's 9 mm under a G1's 20 % ramp).  With v_ref + s − b ṡ the pair
    is consistent again (:meth:`vrp`) and only the observer's own lag remains, F − F̂ = Ḟ/k_F
    (eq. 44).  The rate is the shift's finite difference through a first-order low-pass of
    SHIFT_RATE_TAU_S: continuous (the VRP reference never jumps), and exact on a ramp.
    """

    def __init__(self, dt: float, tau: float = SHIFT_RATE_TAU_S) -> None:
        if not dt > 0.0 or not tau > 0.0:
            raise ValueError(f"dt = {dt}, tau = {tau}: both must be > 0 s")
        self.dt, self.tau = float(dt), float(tau)
        self._share = self.dt / max(self.tau, self.dt)  # of the step to the new difference, a tick
        self.reset()

    def reset(self) -> None:
        """No rate (and no previous shift: the next update only records it)."""
        self._rate = (0.0, 0.0, 0.0)
        self._previous: tuple[float, ...] | None = None

    @property
    def rate(self) -> NDArray:
        """ṡ (m/s), low-passed, after the last update."""
        return np.array(self._rate)

    def update(self, shift: NDArray) -> NDArray:
        """Feed this tick's shift s (m); returns the low-passed ṡ (m/s)."""
        return np.array(self.update_floats(*np.asarray(shift, dtype=float).tolist()))

    def update_floats(self, sx: float, sy: float, sz: float) -> tuple[float, float, float]:
        """:meth:`update` of the shift (sx, sy, sz) in floats (a per-tick loop's 3-vectors:
        numpy's per-call overhead would be most of the cost), the same operations."""
        rx, ry, rz = self._rate
        previous = self._previous
        if previous is not None:
            dt, share = self.dt, self._share
            raw_x = (sx - previous[0]) / dt
            raw_y = (sy - previous[1]) / dt
            raw_z = (sz - previous[2]) / dt
            rx, ry, rz = (
                rx + share * (raw_x - rx),
                ry + share * (raw_y - ry),
                rz + share * (raw_z - rz),
            )
            self._rate = (rx, ry, rz)
        self._previous = (sx, sy, sz)
        return rx, ry, rz

    def vrp(self, v_shifted: NDArray, b: float) -> NDArray:
        """v_ref + s − b ṡ from the shifted v_ref + s: the VRP of the shifted DCM reference."""
        return np.asarray(v_shifted, dtype=float) - b * self.rate
