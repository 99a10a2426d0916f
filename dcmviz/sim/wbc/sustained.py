"""The sustained part of the estimated external load, which the feet take; the rest is a push."""

from __future__ import annotations

import numpy as np


class SustainedLoad:
    """The part of F̂ (the walker's, eq. 45) and τ̂ (:class:`MomentObserver`) that has lasted T:
    per component, the value of the smallest magnitude over the last T seconds if the sign did
    not change (0 otherwise).  A pull held for seconds passes, T late (the feet take it and the
    robot leans into it); a push shorter than T does not, at any moment of it or after it: its
    moment about the CoM is absorbed as centroidal angular momentum (the trunk rolls with it and
    is righted afterwards) instead of pulling the CMP inside the sole.  A low-pass filter would
    keep a push's moment at the feet for T after the push has gone.  T = 0: all is sustained.
    """

    def __init__(self, time_constant_s: float, dt: float = 0.002) -> None:
        self.time_constant_s = float(time_constant_s)
        self._n = max(1, round(self.time_constant_s / dt)) if self.time_constant_s > 0 else 0
        self._window = np.zeros((6, self._n))  # one row per component: min/max along rows
        self.reset()

    def reset(self) -> None:
        self.force = np.zeros(3)
        self.moment = np.zeros(3)
        self._window[:] = 0.0
        self._i = 0

    def get_state(self) -> tuple[np.ndarray, int, np.ndarray, np.ndarray]:
        """A copy of the window, its index and the present values (a resume from a tick)."""
        return self._window.copy(), self._i, self.force.copy(), self.moment.copy()

    def set_state(self, state: tuple[np.ndarray, int, np.ndarray, np.ndarray]) -> None:
        """Continue from :meth:`get_state`'s copy."""
        window, self._i, force, moment = state
        self._window[:] = window
        self.force, self.moment = force.copy(), moment.copy()

    def update(self, t: float, force: np.ndarray, moment: np.ndarray) -> None:
        """Take the present estimates (N, N m) at time ``t`` (s; one sample per control tick)."""
        if self._n == 0:
            self.force = np.array(force, dtype=float)
            self.moment = np.array(moment, dtype=float)
            return
        column = self._window[:, self._i]
        column[:3] = force
        column[3:] = moment
        self._i = (self._i + 1) % self._n
        low = self._window.min(axis=1).tolist()
        high = self._window.max(axis=1).tolist()
        value = [
            lo if lo > 0.0 else hi if hi < 0.0 else 0.0 for lo, hi in zip(low, high, strict=True)
        ]
        self.force = np.array(value[:3])
        self.moment = np.array(value[3:])
