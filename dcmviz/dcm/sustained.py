"""The sustained part of the estimated external load, which the feet take; the rest is a push."""

from __future__ import annotations

import math

import numpy as np

RAMP_TOLERANCE = 0.1  # of the change over the window: a steady ramp's quarters lie this close
RAMP_FLOOR = (1.0, 0.5)  # N, N m: smaller changes (and deviations) are the estimates' noise


class SustainedLoad:
    """The part of F̂ (the walker's, eq. 45) and τ̂ (:class:`MomentObserver`) that has lasted T:
    per component, the value of the smallest magnitude over the last T seconds if the sign did
    not change (0 otherwise).  A pull held for seconds passes, T late (the feet take it and the
    robot leans into it); a push shorter than T does not, at any moment of it or after it: its
    moment about the CoM is absorbed as centroidal angular momentum (the trunk rolls with it and
    is righted afterwards) instead of pulling the CMP inside the sole.  A low-pass filter would
    keep a push's moment at the feet for T after the push has gone.  T = 0: all is sustained.

    A component that has changed steadily over the whole window (a ramp: its values at the
    window's quarters within RAMP_TOLERANCE of the line between its ends, no sign change) is
    sustained at its present value: a load growing for T is no push, and the min over the window
    leaves a ramp's last T of growth to the angular momentum, which then grows for as long as the
    ramp goes on (Talos under the tug of war ramped to 35 % of m g fell at 16 %, before the ramp
    reached what it holds).

    ``settle_s`` > 0: the passed load follows that value with a first-order lag of this time
    constant instead of taking it at once.  The value itself jumps where the rules switch (a ramp
    recognised after T passes its present value, not the window's oldest; a held force that ends
    drops at once), and the walker shifts its references by the held moment (the lean), so a jump
    there was a jump of the DCM reference: 7.7 mm in one tick in the paper's tug of war on Talos.
    """

    def __init__(self, time_constant_s: float, dt: float = 0.002, settle_s: float = 0.0) -> None:
        self.time_constant_s = float(time_constant_s)
        self._n = max(1, round(self.time_constant_s / dt)) if self.time_constant_s > 0 else 0
        # the lag's share of the remaining step taken per tick (exact for a value held over it)
        self._settle = 1.0 - math.exp(-dt / settle_s) if settle_s > 0 else 1.0
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
        n, i = self._n, self._i  # the oldest sample is at i, the newest at i - 1
        if n >= 4:
            ends = self._window[:, [i % n, (i + n // 4) % n, (i + n // 2) % n,
                                    (i + 3 * n // 4) % n, (i - 1) % n]].tolist()  # fmt: skip
            for k, (a, q1, q2, q3, e) in enumerate(ends):
                if value[k] == 0.0:
                    continue  # the sign changed: nothing held
                span = e - a
                tol = RAMP_TOLERANCE * abs(span) + RAMP_FLOOR[k // 3]
                if (
                    abs(span) > RAMP_FLOOR[k // 3]
                    and abs(q1 - (a + 0.25 * span)) <= tol
                    and abs(q2 - (a + 0.5 * span)) <= tol
                    and abs(q3 - (a + 0.75 * span)) <= tol
                ):
                    value[k] = e
        if self._settle < 1.0:  # first-order lag towards the value, in place
            a = self._settle
            self.force += a * (np.array(value[:3]) - self.force)
            self.moment += a * (np.array(value[3:]) - self.moment)
            return
        self.force = np.array(value[:3])
        self.moment = np.array(value[3:])
