"""Swing-foot paths: C² in time from lift-off to touchdown, re-targetable mid-swing (step adjustment)."""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dcmviz.gait.terrain import Terrain
from dcmviz.robots.feet import Footstep

_REST = (0.0, 0.0, 0.0)  # zero rate and acceleration of x, y, yaw (lift-off, touchdown)

SWING_HEIGHT_M = 0.06  # apex of the swing above the higher of lift-off and touchdown
RETARGET_FREEZE = 0.8  # the swing target is frozen for the last 20 % of single support
PATH_SAMPLES = 24  # points of SwingTrajectory.path (the drawn path)


Columns = tuple[tuple[float, ...], ...]  # per component: the 6 coefficients of a quintic


def _quintic_coefficients(
    p0: Sequence[float], v0: Sequence[float], a0: Sequence[float], p1: Sequence[float], T: float
) -> Columns:
    """Coefficients of p(τ) = Σ c_i τ^i with p, ṗ, p̈ given at 0 and p(T) = p1, ṗ = p̈ = 0, per
    component (c_0 … c_5 of x, of y, of yaw).

    In Python floats (the components are 3: numpy's per-call overhead would be most of the cost,
    and a re-targeted swing solves this every tick), the same operations in the same order as
    the vector form."""
    T2, T3, T4, T5 = T * T, T**3, T**4, T**5
    columns = []
    for q0, q1, qa, qe in zip(p0, v0, a0, p1, strict=True):
        c2 = 0.5 * qa
        d = qe - (q0 + q1 * T + c2 * T2)
        e = -(q1 + 2 * c2 * T)
        f = -(2 * c2)
        columns.append((
            q0, q1, c2,
            (10 * d - 4 * e * T + 0.5 * f * T2) / T3,
            (-15 * d + 7 * e * T - f * T2) / T4,
            (6 * d - 3 * e * T + 0.5 * f * T2) / T5,
        ))  # fmt: skip
    return tuple(columns)


EDGE_CLEARANCE_M = 0.03  # over terrain, the sole passes every edge at least this high


# over terrain, the sole rises in the first 35 % of the swing and lowers in the last 35 %
RISE_FRACTION = 0.35


def _smoothstep5(u: np.ndarray | float) -> tuple:
    """q(u) = u³(10 − 15u + 6u²) clipped to [0, 1], with dq/du and d²q/du² (0 at both ends)."""
    u = np.clip(u, 0.0, 1.0)
    return (
        u**3 * (10 - 15 * u + 6 * u * u),
        30 * u * u * (1 - u) ** 2,
        60 * u * (1 - u) * (1 - 2 * u),
    )


def _terrain_profile(s: np.ndarray | float) -> tuple:
    """Rise R(s) (0 → 1 over [0, σ]) and fall F(s) (0 → 1 over [1 − σ, 1]), σ = RISE_FRACTION,
    with their first and second derivatives in s: z(s) = z0 + (z_top − z0) R + (z1 − z_top) F."""
    sigma = RISE_FRACTION
    r, dr, ddr = _smoothstep5(np.asarray(s) / sigma)
    f, df, ddf = _smoothstep5((np.asarray(s) - (1.0 - sigma)) / sigma)
    return r, dr / sigma, ddr / sigma**2, f, df / sigma, ddf / sigma**2


def _top_over(
    terrain: Terrain,
    lift: Footstep,
    touch: Footstep,
    sole: tuple[float, float],
    z0: float,
    z1: float,
) -> float:
    """The lowest plateau z_top ≥ max(z0, z1) + SWING_HEIGHT_M of the terrain profile (see
    :class:`SwingTrajectory`) with the sole at least EDGE_CLEARANCE_M above the highest ground
    under it wherever it straddles an edge, and never below the ground elsewhere.

    The sole's centre moves with the quintic q(s) between lift-off and touchdown (as the
    horizontal path does when not re-targeted); the ground under it is sampled at its corners,
    edge mid-points and centre.
    """
    s = np.linspace(0.02, 0.98, 97)
    q = s**3 * (10 - 15 * s + 6 * s * s)
    a, b = 0.5 * sole[0], 0.5 * sole[1]
    offsets = np.array(
        [[u * a, v * b] for u in (-1.0, 0.0, 1.0) for v in (-1.0, 0.0, 1.0)]
    )  # (9, 2) in the sole frame
    yaw = lift.yaw + (touch.yaw - lift.yaw) * q
    c, sn = np.cos(yaw), np.sin(yaw)
    centre = lift.position[:2] + np.outer(q, touch.position[:2] - lift.position[:2])  # (97, 2)
    px = centre[:, None, 0] + c[:, None] * offsets[:, 0] - sn[:, None] * offsets[:, 1]
    py = centre[:, None, 1] + sn[:, None] * offsets[:, 0] + c[:, None] * offsets[:, 1]
    heights = terrain.height_at(np.stack([px, py], axis=-1))  # (97, 9)
    ground = heights.max(axis=1)
    straddle = np.ptp(heights, axis=1) > 1e-9
    need = ground + np.where(straddle, EDGE_CLEARANCE_M, 0.0)
    r, _, _, f, _, _ = _terrain_profile(s)
    # z(s) = z0 (1 − R) + z1 F + z_top (R − F) ≥ need, with R − F > 0 inside (0, 1)
    bound = (need - z0 * (1 - r) - z1 * f) / np.maximum(r - f, 1e-12)
    # at most the highest ground under the path plus the edge clearance and the apex: a sole
    # that lands (or lifts off) across an edge needs the clearance where R - F → 0, which no
    # plateau gives (an iCub stairs walk asked for 15 m); the feasibility check warns of it
    ceiling = max(z0, z1, float(ground.max())) + EDGE_CLEARANCE_M + SWING_HEIGHT_M
    return float(min(max(max(z0, z1) + SWING_HEIGHT_M, bound.max()), ceiling))


SOLE_CLEARANCE_M = 0.03  # a swing sole passes the stance sole at least this far from it
DETOUR_SAMPLES = 24  # points of a path checked against the stance sole
MAX_DETOUR_M = 0.3  # the farthest a swing goes round the stance sole


def _bump_value(s: np.ndarray | float) -> np.ndarray | float:
    """B(s) = 64 s³ (1 − s)³ for s in [0, 1] (floats or arrays): the detour's and the swing
    height's profile."""
    return 64 * s**3 * (1 - s) ** 3


def _bump(s: float) -> tuple[float, float, float]:
    """B(s) = 64 s³ (1 − s)³ (1 at mid-swing; zero value, rate and acceleration at both ends)
    with dB/ds and d²B/ds²."""
    if s <= 0.0 or s >= 1.0:
        return 0.0, 0.0, 0.0
    return (
        64 * s**3 * (1 - s) ** 3,
        192 * s * s * (1 - s) ** 2 * (1 - 2 * s),
        192 * s * (1 - s) * (2 - 10 * s + 10 * s * s),
    )


def _gap_to_sole(points: np.ndarray, stance: Footstep, sole: tuple[float, float]) -> np.ndarray:
    """Per point (n, 2): how far a sole centred there (its axes the stance sole's) lies from the
    stance sole (m; ≤ 0: they overlap), the larger of the two axes' separations."""
    c, s = math.cos(stance.yaw), math.sin(stance.yaw)
    d = points - stance.position[:2]
    x, y = d[:, 0] * c + d[:, 1] * s, -d[:, 0] * s + d[:, 1] * c
    return np.maximum(np.abs(x) - sole[0], np.abs(y) - sole[1])


def detour(
    columns: Columns, T: float, stance: Footstep, sole: tuple[float, float]
) -> tuple[float, float]:
    """The horizontal detour d n (m) that keeps a swing sole on the quintic ``columns`` (x, y
    and yaw's coefficients, :func:`_quintic_coefficients`, over [0, T]) SOLE_CLEARANCE_M clear
    of the ``stance`` sole: none if the quintic does; else round its toe or heel or out to one
    side (n = ± its x or y axis), the smallest d (1 cm steps, at most MAX_DETOUR_M) that clears
    it, or no closer than the path's ends are (a target still moving across)."""
    if sole[0] <= 0.0:
        return 0.0, 0.0
    # both ends well to one side of the stance sole (every ordinary step): nothing to go around;
    # in floats (a re-targeted swing asks every tick)
    c, sn = math.cos(stance.yaw), math.sin(stance.yaw)
    cx, cy = columns[0], columns[1]
    x0, y0 = cx[0], cy[0]
    T_powers = [T**i for i in range(6)]
    x1 = sum(cx[i] * T_powers[i] for i in range(6))
    y1 = sum(cy[i] * T_powers[i] for i in range(6))
    sx, sy = stance.position[:2].tolist()
    lat0 = -(x0 - sx) * sn + (y0 - sy) * c
    lat1 = -(x1 - sx) * sn + (y1 - sy) * c
    if lat0 * lat1 > 0.0 and min(abs(lat0), abs(lat1)) >= sole[1] + SOLE_CLEARANCE_M:
        return 0.0, 0.0
    s = np.linspace(0.0, 1.0, DETOUR_SAMPLES + 1)[1:-1]
    tau = s * T
    powers = np.stack([tau**i for i in range(6)], axis=1)
    path = powers @ np.array(columns).T[:, :2]
    gap = _gap_to_sole(path, stance, sole)
    # no closer than the ends themselves are (a target being moved across may still be near it)
    ends = _gap_to_sole(np.array([[x0, y0], [x1, y1]]), stance, sole)
    need = min(SOLE_CLEARANCE_M, float(ends.min()))
    if gap.min() >= need - 1e-9:
        return 0.0, 0.0
    c, sn = math.cos(stance.yaw), math.sin(stance.yaw)
    bump = _bump_value(s)
    best, best_gap = (0.0, 0.0), float(gap.min())
    for d in np.arange(0.01, MAX_DETOUR_M + 1e-9, 0.01):
        # round the toe or the heel, or out to either side: the first to clear at this size
        for axis in ((c, sn), (-c, -sn), (-sn, c), (sn, -c)):
            way = (float(d * axis[0]), float(d * axis[1]))
            clear = float(_gap_to_sole(path + np.outer(bump, way), stance, sole).min())
            if clear > best_gap:
                best, best_gap = way, clear
        if best_gap >= need - 1e-9:
            break
    return best


@dataclass(frozen=True)
class SwingTrajectory:
    """A swing foot path from lift-off to touchdown: C² in time, re-targetable mid-swing.

    Horizontal position and yaw follow a quintic to the target with zero end velocity and
    acceleration; the height follows z0 + (z1 − z0) q(s) + h 64 s³ (1 − s)³ (zero velocity and
    acceleration at both ends, apex h above the straight line at mid-swing).

    Over terrain (``top`` set) the sole rises first, then travels, then lowers: z(s) = z0 +
    (top − z0) R(s) + (z1 − top) F(s), R rising 0 → 1 over the first RISE_FRACTION of the swing
    and F over the last (quintic smoothsteps: C², zero velocity and acceleration at both ends),
    ``top`` the lowest plateau that clears every edge under the sole by EDGE_CLEARANCE_M.  A bump
    over the straight line would have to rise far higher to clear a riser early in the swing.
    """

    t_lift: float
    t_touch: float
    start: np.ndarray  # (3,) lift-off position
    target: np.ndarray  # (3,) touchdown position
    yaw_start: float
    yaw_target: float
    height: float
    t_seg: float = 0.0  # start time of the current horizontal segment
    # x, y, yaw quintic from t_seg to t_touch: each one's coefficients c_0 … c_5 (floats)
    columns: Columns = ()
    top: float | None = None  # m, plateau height over terrain (None: the bump of flat ground)
    # around the stance foot (a crossing step): the sole and the leg to keep clear of, and the
    # horizontal detour d · 64 s³(1 − s)³ n added to the quintic over its segment
    stance: Footstep | None = None
    sole: tuple[float, float] = (0.0, 0.0)  # length, width of the soles (m)
    detour: tuple[float, float] = (0.0, 0.0)  # d n (m, world x-y); zero on most steps

    @staticmethod
    def between(
        t_lift: float,
        t_touch: float,
        lift: Footstep,
        touch: Footstep,
        clearance: float = SWING_HEIGHT_M,
        terrain: Terrain | None = None,
        sole: tuple[float, float] = (0.0, 0.0),
        stance: Footstep | None = None,
    ) -> SwingTrajectory:
        """The path from ``lift`` to ``touch``; over a ``terrain`` its apex is raised until the
        sole (``sole`` = length, width, m) passes every edge under it with ``EDGE_CLEARANCE_M``.
        With ``stance`` (the foot standing while this one swings) the path goes around it
        where the straight one would not keep clear of it (a crossing step, :func:`detour`)."""
        z0, z1 = float(lift.position[2]), float(touch.position[2])
        height = clearance + 0.5 * abs(z1 - z0)
        top = None
        if terrain is not None and not terrain.flat:
            top = _top_over(terrain, lift, touch, sole, z0, z1)
            height = top - 0.5 * (z0 + z1)
        yaw1 = lift.yaw + math.remainder(touch.yaw - lift.yaw, 2 * math.pi)
        p0 = (*lift.position[:2].tolist(), lift.yaw)
        p1 = (*touch.position[:2].tolist(), yaw1)
        c = _quintic_coefficients(p0, _REST, _REST, p1, t_touch - t_lift)
        way = detour(c, t_touch - t_lift, stance, sole) if stance is not None else (0.0, 0.0)
        return SwingTrajectory(
            t_lift,
            t_touch,
            np.array(lift.position, float),
            np.array(touch.position, float),
            lift.yaw,
            yaw1,
            height,
            t_lift,
            c,
            top,
            stance,
            sole,
            way,
        )

    def frozen(self, t: float) -> bool:
        """True in the last 20 % of the swing, where the target no longer moves."""
        return t >= self.t_lift + RETARGET_FREEZE * (self.t_touch - self.t_lift)

    def retarget(self, t: float, target: np.ndarray) -> SwingTrajectory:
        """A path that agrees with this one in position, velocity, acceleration at t, ending at target.

        In the last 20 % of the swing the target is frozen (large accelerations otherwise).
        """
        if self.frozen(t) or t >= self.t_touch:
            return self
        target = np.asarray(target, dtype=float)
        if abs(target[0] - self.target[0]) < 1e-6 and abs(target[1] - self.target[1]) < 1e-6:
            return self
        t = max(t, self.t_seg)
        p, v, a = self._horizontal(t)
        p1 = (float(target[0]), float(target[1]), self.yaw_target)
        c = _quintic_coefficients(p, v, a, p1, self.t_touch - t)
        new_target = np.array([target[0], target[1], self.target[2]])
        way = detour(c, self.t_touch - t, self.stance, self.sole) if self.stance else (0.0, 0.0)
        return SwingTrajectory(
            self.t_lift,
            self.t_touch,
            self.start,
            new_target,
            self.yaw_start,
            self.yaw_target,
            self.height,
            t,
            c,
            self.top,
            self.stance,
            self.sole,
            way,
        )

    def retime(self, t: float, t_touch: float) -> SwingTrajectory:
        """The same swing with touchdown at ``t_touch`` (step timing, ``dcmviz.gait.timing``).

        The height keeps its progress s at t (the lift-off time is moved so that
        (t − t_lift)/(t_touch − t_lift) is unchanged): z is continuous and its rate changes by
        the ratio of the durations.  The horizontal quintic is re-solved from its position,
        velocity and acceleration at t, so it stays C².
        """
        if abs(t_touch - self.t_touch) < 1e-9 or t >= self.t_touch or t_touch <= t:
            return self
        s = min(max((t - self.t_lift) / (self.t_touch - self.t_lift), 0.0), 1.0)
        if s >= 1.0:
            return self
        t_lift = (t - s * t_touch) / (1.0 - s)
        t = max(t, self.t_seg)
        p, v, a = self._horizontal(t)
        p1 = (float(self.target[0]), float(self.target[1]), self.yaw_target)
        c = _quintic_coefficients(p, v, a, p1, t_touch - t)
        way = detour(c, t_touch - t, self.stance, self.sole) if self.stance else (0.0, 0.0)
        return SwingTrajectory(
            t_lift, t_touch, self.start, self.target, self.yaw_start, self.yaw_target,
            self.height, t, c, self.top, self.stance, self.sole, way,
        )  # fmt: skip

    def _horizontal(self, t: float) -> tuple[list[float], list[float], list[float]]:
        """x, y, yaw and their rates and accelerations at global time t (floats)."""
        tau = min(max(t, self.t_seg), self.t_touch) - self.t_seg
        columns = self.columns  # Horner, per component in floats
        p = [c0 + tau * (c1 + tau * (c2 + tau * (c3 + tau * (c4 + tau * c5))))
             for c0, c1, c2, c3, c4, c5 in columns]  # fmt: skip
        v = [c1 + tau * (2 * c2 + tau * (3 * c3 + tau * (4 * c4 + tau * 5 * c5)))
             for _, c1, c2, c3, c4, c5 in columns]  # fmt: skip
        a = [2 * c2 + tau * (6 * c3 + tau * (12 * c4 + tau * 20 * c5))
             for _, _, c2, c3, c4, c5 in columns]  # fmt: skip
        if self.detour != (0.0, 0.0) and t < self.t_touch:
            T = self.t_touch - self.t_seg
            b, db, ddb = _bump(tau / T)
            for i in (0, 1):
                p[i] += self.detour[i] * b
                v[i] += self.detour[i] * db / T
                a[i] += self.detour[i] * ddb / (T * T)
        if t >= self.t_touch:
            return p, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
        return p, v, a

    @functools.cached_property
    def path(self) -> np.ndarray:
        """(PATH_SAMPLES, 3) sole positions along the path still to go: from the start of the
        current segment (lift-off, or the last re-targeting) to touchdown, evenly in time; the
        same numbers as :meth:`sample` at those times, for all of them at once (drawn)."""
        T = self.t_touch - self.t_lift
        T_seg = self.t_touch - self.t_seg
        tau = np.linspace(0.0, T_seg, PATH_SAMPLES)
        out = np.empty((PATH_SAMPLES, 3))
        out[:, :2] = np.vander(tau, 6, increasing=True) @ self.coeffs[:, :2]
        if self.detour != (0.0, 0.0) and T_seg > 0.0:
            u = tau / T_seg
            out[:, :2] += np.outer(_bump_value(u), self.detour)
        s = np.clip((self.t_seg + tau - self.t_lift) / T, 0.0, 1.0)
        z0, z1 = self.start[2], self.target[2]
        if self.top is not None:
            r, _, _, f, _, _ = _terrain_profile(s)
            out[:, 2] = z0 + (self.top - z0) * r + (z1 - self.top) * f
        else:
            out[:, 2] = z0 + (z1 - z0) * _smoothstep5(s)[0] + self.height * _bump_value(s)
        out.flags.writeable = False
        return out

    @functools.cached_property
    def coeffs(self) -> np.ndarray:
        """(6, 3): the x, y, yaw quintic's coefficients (``columns``) as one matrix."""
        return np.array(self.columns).T

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
        """Position, velocity, acceleration (3,), yaw and yaw rate at global time t."""
        T = self.t_touch - self.t_lift
        s = min(max((t - self.t_lift) / T, 0.0), 1.0)
        p, v, a = self._horizontal(t)
        z0, z1 = self.start[2], self.target[2]
        if self.top is not None:
            r, dr, ddr, f, df, ddf = _terrain_profile(s)
            z = z0 + (self.top - z0) * r + (z1 - self.top) * f
            dz = ((self.top - z0) * dr + (z1 - self.top) * df) / T
            ddz = ((self.top - z0) * ddr + (z1 - self.top) * ddf) / (T * T)
            return (
                np.array([p[0], p[1], float(z)]),
                np.array([v[0], v[1], float(dz)]),
                np.array([a[0], a[1], float(ddz)]),
                float(p[2]),
                float(v[2]),
            )
        q = s**3 * (10 - 15 * s + 6 * s * s)
        dq = 30 * s * s * (1 - s) ** 2
        ddq = 60 * s * (1 - s) * (1 - 2 * s)
        bump = 64 * s**3 * (1 - s) ** 3
        dbump = 192 * s * s * (1 - s) ** 2 * (1 - 2 * s)
        ddbump = 192 * s * (1 - s) * (2 - 10 * s + 10 * s * s) if 0 < s < 1 else 0.0
        z = z0 + (z1 - z0) * q + self.height * bump
        dz = ((z1 - z0) * dq + self.height * dbump) / T
        ddz = ((z1 - z0) * ddq + self.height * ddbump) / (T * T)
        if s <= 0.0 or s >= 1.0:
            dz = ddz = 0.0
        pos = np.array([p[0], p[1], z])
        vel = np.array([v[0], v[1], dz])
        acc = np.array([a[0], a[1], ddz])
        return pos, vel, acc, float(p[2]), float(v[2])
