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
        self._count_signs()

    def _count_signs(self) -> None:
        """Per component, how many samples in the window are > 0 and < 0: the sign rule needs
        the window's min or max only for a component of one sign throughout (a held load), and
        the counts, kept up to date per sample, say which without reading the window.  The
        window's min and max per component are kept with their sample's index (None: read the
        window again), so a tick reads the window only where its extreme has just left it."""
        self._positive = (self._window > 0.0).sum(axis=1).tolist()
        self._negative = (self._window < 0.0).sum(axis=1).tolist()
        self._lowest: list[tuple[float, int] | None] = [None] * 6
        self._highest: list[tuple[float, int] | None] = [None] * 6

    def _extreme(self, k: int, cache: list, pick) -> float:
        """The window's min (``pick`` = argmin) or max of component k, read again if unknown."""
        known = cache[k]
        if known is None:
            j = int(pick(self._window[k]))
            known = cache[k] = (self._window.item(k, j), j)
        return known[0]

    def get_state(self) -> tuple[np.ndarray, int, np.ndarray, np.ndarray]:
        """A copy of the window, its index and the present values (a resume from a tick)."""
        return self._window.copy(), self._i, self.force.copy(), self.moment.copy()

    def set_state(self, state: tuple[np.ndarray, int, np.ndarray, np.ndarray]) -> None:
        """Continue from :meth:`get_state`'s copy."""
        window, self._i, force, moment = state
        self._window[:] = window
        self.force, self.moment = force.copy(), moment.copy()
        self._count_signs()

    def update(self, t: float, force: np.ndarray, moment: np.ndarray) -> None:
        """Take the present estimates (N, N m) at time ``t`` (s; one sample per control tick)."""
        n = self._n
        if n == 0:
            self.force = np.array(force, dtype=float)
            self.moment = np.array(moment, dtype=float)
            return
        window, i = self._window, self._i
        old = window[:, i].tolist()
        new = [*np.asarray(force, dtype=float).tolist(), *np.asarray(moment, dtype=float).tolist()]
        window[:, i] = new
        self._i = i = (i + 1) % n  # the oldest sample is at i, the newest at i - 1
        positive, negative = self._positive, self._negative
        lowest, highest = self._lowest, self._highest
        slot = (i - 1) % n  # where the new sample went
        value = [0.0] * 6
        quarters = None  # per component the window's oldest sample and its quarters, if needed
        for k in range(6):
            x = new[k]
            positive[k] += (x > 0.0) - (old[k] > 0.0)
            negative[k] += (x < 0.0) - (old[k] < 0.0)
            # the extremes: the new sample replaces them if it is beyond (ties: the newer index,
            # which leaves later); one that has just been overwritten is read again when needed
            low, high = lowest[k], highest[k]
            if low is not None and (x <= low[0] or low[1] == slot):
                lowest[k] = (x, slot) if x <= low[0] else None
            if high is not None and (x >= high[0] or high[1] == slot):
                highest[k] = (x, slot) if x >= high[0] else None
            if positive[k] == n:  # one sign throughout: the smallest magnitude
                value[k] = self._extreme(k, lowest, np.argmin)
            elif negative[k] == n:
                value[k] = self._extreme(k, highest, np.argmax)
            else:
                continue  # the sign changed (or a sample is 0): nothing held
            if n < 4:
                continue
            if quarters is None:  # read once for every component held this tick
                quarters = window[:, [i, (i + n // 4) % n, (i + n // 2) % n,
                                      (i + 3 * n // 4) % n]].tolist()  # fmt: skip
            a, q1, q2, q3 = quarters[k]
            e = x  # the newest sample
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
            f, m = self.force, self.moment
            f0, f1, f2 = f.tolist()  # as floats: the same operations as on the arrays
            m0, m1, m2 = m.tolist()
            f[:] = (f0 + a * (value[0] - f0), f1 + a * (value[1] - f1), f2 + a * (value[2] - f2))
            m[:] = (m0 + a * (value[3] - m0), m1 + a * (value[4] - m1), m2 + a * (value[5] - m2))
            return
        self.force = np.array(value[:3])
        self.moment = np.array(value[3:])
