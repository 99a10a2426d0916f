"""Multi-step VRP and DCM preview in closed form (Sec. II-C, eqs. 5, 10, 13–23).

Every block of the paper's matrices is (scalar)·I₃, so the mappings are stored as scalar
weight matrices W (n_phi, n_wp) with A = kron(W, I₃). ξ_ref_0 and ξ_ref_T are computed by the
O(n) backward iteration of eqs. (15), (17), (18) instead of the O(n³) inverses of eqs. (20),
(21); the dense 3n matrices are built only on request.

Phases are indexed from 0 here (φ = 1 … n_φ in the paper); phase φ runs from waypoint φ to
waypoint φ + 1 (eqs. 11, 12).

Sampling eq. (10): ξ_ref(t) = v_ref_0 + β(t) Δv + γ(t) (ξ_ref_T − v_ref_0), Δv = v_ref_T − v_ref_0
(α + β + γ = 1). Where the closed form is well conditioned (``closed_form_error_bound`` ≤ 64,
e.g. T/b ≥ 1.94 for order 5) β = σ(t) − γ σ_T, so ξ_ref = v_ref_0 + σ(t) Δv + γ(t) r with
r = ξ_ref_T − v_ref_0 − σ_T Δv: a degree-n polynomial and one exponential per sample. In shorter
phases σ's terms cancel (module docstring of ``interpolation``) and β is the power series of
``beta_series_coefficients`` in s = 2t/T − 1 (about 20 terms at most), r = ξ_ref_T − v_ref_0.
α_0, β_0 of eq. (15) come from the integral form (``alpha_beta_0``) for every phase.
"""

from __future__ import annotations

import bisect
import math
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dcmviz.dcm.interpolation import (
    CLOSED_FORM_ERROR_BOUND,
    alpha_beta_0,
    beta_series_coefficients,
    check_b,
    check_durations,
    check_order,
    check_points,
    closed_form_error_bound,
    f_tau_coefficients,
    sigma_tau_coefficients,
)

_I3 = np.eye(3)
Triple = tuple[float, float, float]  # a 3-vector in floats (the per-tick scalar path)


def _read_only(array: NDArray) -> NDArray:
    array.flags.writeable = False
    return array


class PhaseSchedule:
    """The waypoint-independent part of a preview: durations T_φ, b, order and eq. (15).

    Holds α_0,φ, β_0,φ, γ_0,φ of eq. (15), the σ polynomials of eq. (8) per phase, and the
    scalar weight matrices of eqs. (20), (21) (computed lazily). Shared by every Preview built
    from the same timing, since the mappings are linear in the waypoints. ``closed_form[φ]``
    says whether phase φ is sampled by eq. (10) as printed or by the series of β (module
    docstring).
    """

    def __init__(self, durations: ArrayLike, b: float, order: int) -> None:
        self.order = check_order(order)
        self.b = check_b(b)
        self.durations = check_durations(durations)
        T = self.durations
        self.n_phases = int(T.size)
        self.n_waypoints = self.n_phases + 1
        # S[φ] = global start time of phase φ; S[n_φ] = total duration.
        self.boundaries = _read_only(np.concatenate(([0.0], np.cumsum(T))))
        self.phase_start_times = _read_only(self.boundaries[:-1].copy())
        self.duration = float(self.boundaries[-1])

        # Table I / eq. (8) in normalised time τ = t / T: f(τ) is the same for every phase,
        # σ(τ) depends on b / T_φ. Time derivatives carry a factor 1 / T_φ. (For T ≪ b these
        # are the paper's σ, huge; sampling does not use them there.)
        self.f_coefficients = _read_only(f_tau_coefficients(self.order))
        self.f_dot_coefficients = _read_only(f_tau_coefficients(self.order, 1))
        with np.errstate(over="ignore", invalid="ignore"):  # b/T > 1e60: σ overflows
            s = sigma_tau_coefficients(T, self.b, self.order)
            k = np.arange(1, s.shape[1])
            sigma_dot = s[:, 1:] * k if s.shape[1] > 1 else np.zeros((self.n_phases, 1))
            sigma_T = s.sum(axis=1)
        self.sigma_coefficients = _read_only(s)
        self.sigma_dot_coefficients = _read_only(sigma_dot)
        self.sigma_0 = _read_only(s[:, 0].copy())
        self.sigma_T = _read_only(sigma_T)
        # eq. (15), α_0 and β_0 from the integral form (accurate for every T / b)
        self.gamma_0 = _read_only(np.exp(-T / self.b))
        # Sampling (module docstring): p(t) = σ(t) and p_T = σ_T where the closed form is
        # well conditioned; p(t) = β(t) from a series in s = 2t/T − 1 and p_T = 0 elsewhere.
        closed = closed_form_error_bound(T, self.b, self.order) <= CLOSED_FORM_ERROR_BOUND
        series = np.flatnonzero(~closed)
        alpha_0, beta_0 = alpha_beta_0(T, self.b, self.order)  # integral form, every T / b
        self.alpha_0 = _read_only(alpha_0)
        self.beta_0 = _read_only(beta_0)
        self.closed_form = _read_only(closed)
        self._p_coefficients = np.where(closed[:, None], s, 0.0)
        self._p_dot_coefficients = np.where(closed[:, None], sigma_dot, 0.0)
        self._p_T = _read_only(np.where(closed, sigma_T, 0.0))
        self._any_series = bool(series.size)
        self._all_series = series.size == self.n_phases
        self._series_row = np.full(self.n_phases, -1)
        self._series_row[series] = np.arange(series.size)
        self._beta_series = (
            beta_series_coefficients(T[series], self.b, self.order)
            if series.size
            else np.zeros((0, 1))
        )

        # Plain-float copies for the per-tick scalar path: per phase, p's coefficients
        # (descending, for Horner), whether p is the series in s, σ̇'s coefficients and p_T.
        self._starts = self.phase_start_times.tolist()
        self._T = T.tolist()
        self._f = self.f_coefficients[::-1].tolist()
        self._f_dot = self.f_dot_coefficients[::-1].tolist()
        self._p = self._p_coefficients[:, ::-1].tolist()
        for phi, row in zip(series.tolist(), self._beta_series[:, ::-1].tolist(), strict=True):
            self._p[phi] = row
        self._centred = (~closed).tolist()
        self._p_dot = self._p_dot_coefficients[:, ::-1].tolist()
        self._p_T_list = self._p_T.tolist()
        self._xi_ref_T_rows: dict[int, NDArray[np.float64]] = {}  # xi_ref_T_row cache

    def sample_p(self, phi: NDArray, t_phi: NDArray, T: NDArray) -> NDArray[np.float64]:
        """p(t) of the module docstring (σ(t) or β(t)) at local times t_φ of phases φ."""
        if self._all_series:
            return _horner_rows(self._beta_series[phi], (2.0 * t_phi - T) / T)
        p = _horner_rows(self._p_coefficients[phi], t_phi / T)
        if self._any_series:
            row = self._series_row[phi]
            series = row >= 0
            if series.any():
                t_s, T_s = t_phi[series], T[series]
                p[series] = _horner_rows(self._beta_series[row[series]], (2.0 * t_s - T_s) / T_s)
        return p

    def sample_p_dot(self, phi: NDArray, t_phi: NDArray, T: NDArray) -> NDArray[np.float64]:
        """ṗ(t): σ̇(t) where closed form, β̇ = (β − f) / b (eq. 6) in series phases."""
        tau = t_phi / T
        p_dot = _horner_rows(self._p_dot_coefficients[phi], tau) / T
        if self._any_series:
            row = self._series_row[phi]
            series = row >= 0
            if series.any():
                t_s, T_s = t_phi[series], T[series]
                beta = _horner_rows(self._beta_series[row[series]], (2.0 * t_s - T_s) / T_s)
                f = np.polynomial.polynomial.polyval(tau[series], self.f_coefficients)
                p_dot[series] = (beta - f) / self.b
        return p_dot

    # --- phase lookup -----------------------------------------------------------------------

    def locate(self, t: float) -> tuple[int, float]:
        """Phase φ and local time t_φ (eq. 5) of a global scalar time t, clamped to [0, duration]."""
        if t != t:
            raise ValueError(f"t = {t!r}: time must be a number (s), not NaN")
        if t <= 0.0:
            return 0, 0.0
        last = self.n_phases - 1
        if t >= self.duration:
            return last, self._T[last]
        phi = bisect.bisect_right(self._starts, t) - 1
        t_phi = t - self._starts[phi]
        T = self._T[phi]
        return phi, (t_phi if t_phi < T else T)

    def locate_array(self, t: NDArray) -> tuple[NDArray, NDArray]:
        """Phases φ and local times t_φ (eq. 5) of a 1-D array of global times, vectorised."""
        if np.isnan(t).any():
            i = int(np.flatnonzero(np.isnan(t))[0])
            raise ValueError(f"t[{i}] = nan: time must be a number (s), not NaN")
        t = np.clip(t, 0.0, self.duration)
        phi = np.searchsorted(self.phase_start_times, t, side="right") - 1
        np.clip(phi, 0, self.n_phases - 1, out=phi)
        t_phi = np.clip(t - self.phase_start_times[phi], 0.0, self.durations[phi])
        return phi, t_phi

    # --- eqs. (20), (21) as scalar weight matrices ----------------------------------------------

    @cached_property
    def W_xi_ref_T(self) -> NDArray[np.float64]:
        """Scalar (n_phi, n_wp) weights of eq. (21): A_xi_ref_T = kron(W, I₃).

        Backward iteration, eqs. (15), (17), (18): row[n_φ−1] = e_{n_wp−1};
        row[φ−1] = α_0,φ e_φ + β_0,φ e_{φ+1} + γ_0,φ row[φ].
        """
        n = self.n_phases
        W = np.zeros((n, self.n_waypoints))
        W[n - 1, n] = 1.0
        for phi in range(n - 1, 0, -1):
            row = W[phi - 1]
            np.multiply(W[phi, phi:], self.gamma_0[phi], out=row[phi:])
            row[phi] += self.alpha_0[phi]
            row[phi + 1] += self.beta_0[phi]
        return _read_only(W)

    @cached_property
    def W_xi_ref_0(self) -> NDArray[np.float64]:
        """Scalar (n_phi, n_wp) weights of eq. (20): A_xi_ref_0 = kron(W, I₃).

        Eq. (15) row by row: row[φ] = α_0,φ e_φ + β_0,φ e_{φ+1} + γ_0,φ W_xi_ref_T[φ].
        """
        W = self.gamma_0[:, None] * self.W_xi_ref_T
        phases = np.arange(self.n_phases)
        W[phases, phases] += self.alpha_0
        W[phases, phases + 1] += self.beta_0
        return _read_only(W)

    @cached_property
    def A_xi_ref_0(self) -> NDArray[np.float64]:
        """Dense (3 n_phi, 3 n_wp) matrix of eq. (20)."""
        return _read_only(np.kron(self.W_xi_ref_0, _I3))

    @cached_property
    def A_xi_ref_T(self) -> NDArray[np.float64]:
        """Dense (3 n_phi, 3 n_wp) matrix of eq. (21)."""
        return _read_only(np.kron(self.W_xi_ref_T, _I3))

    def xi_ref_T_row(self, phi: int) -> NDArray[np.float64]:
        """Row φ of W_xi_ref_T (eq. 21) in O(n_wp), without the dense matrix.

        Unrolls the backward iteration (15), (17), (18): with G(a, k) = Π_{m=a}^{k−1} γ_0,m
        = exp(−(S_k − S_a)/b), row[φ]_j = G(φ+1, j) α_0,j + G(φ+1, j−1) β_0,j−1 for the
        phases j > φ, and the terminal constraint (17) adds G(φ+1, n_φ) to the last waypoint.
        """
        cache = self._xi_ref_T_rows
        row = cache.get(phi)
        if row is None:  # one row per phase, read by every tick of that phase: cached, read-only
            a = phi + 1
            S = self.boundaries
            G = np.exp((S[a] - S[a:]) / self.b)  # G(a, j) for j = a … n_φ
            row = np.zeros(self.n_waypoints)
            row[a:-1] = G[:-1] * self.alpha_0[a:]
            row[-1] = G[-1]  # terminal constraint (17)
            row[a + 1 :] += G[:-1] * self.beta_0[a:]
            cache[phi] = row = _read_only(row)
        return row

    def first_xi_ref_0_row(self) -> NDArray[np.float64]:
        """Row 0 of W_xi_ref_0 (eq. 20) in O(n_wp): eq. (15) applied to ``xi_ref_T_row(0)``."""
        row = self.gamma_0[0] * self.xi_ref_T_row(0)
        row[0] += self.alpha_0[0]
        row[1] += self.beta_0[0]
        return row

    # --- eqs. (15), (17), (18) on waypoints ----------------------------------------------------

    def backward_iteration(self, waypoints: NDArray) -> tuple[NDArray, NDArray]:
        """ξ_ref_0 and ξ_ref_T (n_phi, 3) of eqs. (20), (21) by O(n) backward iteration.

        ξ_ref_T,last = v_wp,last (17); ξ_ref_0,φ = α_0 v_wp,φ + β_0 v_wp,φ+1 + γ_0 ξ_ref_T,φ (15);
        ξ_ref_T,φ−1 = ξ_ref_0,φ (18).
        """
        c = self.alpha_0[:, None] * waypoints[:-1] + self.beta_0[:, None] * waypoints[1:]
        gamma_0 = self.gamma_0.tolist()
        c_list = c.tolist()
        n = self.n_phases
        xi_0: list[list[float]] = [[0.0, 0.0, 0.0]] * n
        x, y, z = waypoints[-1].tolist()
        for phi in range(n - 1, -1, -1):
            g = gamma_0[phi]
            cx, cy, cz = c_list[phi]
            x, y, z = cx + g * x, cy + g * y, cz + g * z
            xi_0[phi] = [x, y, z]
        xi_ref_0 = np.array(xi_0)
        xi_ref_T = np.empty_like(xi_ref_0)
        xi_ref_T[:-1] = xi_ref_0[1:]
        xi_ref_T[-1] = waypoints[-1]
        return _read_only(xi_ref_0), _read_only(xi_ref_T)


def _horner(coefficients_descending: list[float], x: float) -> float:
    result = 0.0
    for c in coefficients_descending:
        result = result * x + c
    return result


def _horner_rows(coefficients: NDArray, x: NDArray) -> NDArray:
    """Σ_k coefficients[:, k] x^k for each row (N, K) and x (N,)."""
    result = np.zeros_like(x)
    for k in range(coefficients.shape[1] - 1, -1, -1):
        result *= x
        result += coefficients[:, k]
    return result


class Preview:
    """Closed-form multi-step VRP and DCM reference trajectories (Sec. II, eqs. 5, 10, 13–23).

    ``waypoints`` (n_wp, 3) are the VRP waypoints v_wp (m), ``durations`` (n_wp − 1,) the
    transition phase durations T_φ (s), ``b`` the DCM time constant (s), ``order`` the VRP
    polynomial order n_poly of Table I (0, 1, 3 or 5). Immutable once built.

    Time arguments are global times (s) clamped to [0, duration]; a float gives a (3,) result,
    a 1-D array of N times an (N, 3) result.
    """

    def __init__(self, waypoints: ArrayLike, durations: ArrayLike, b: float, order: int) -> None:
        schedule = PhaseSchedule(durations, b, order)
        self._init(schedule, _check_waypoints(waypoints, schedule.n_phases))

    @classmethod
    def _from_schedule(cls, schedule: PhaseSchedule, waypoints: NDArray) -> Preview:
        preview = cls.__new__(cls)
        preview._init(schedule, waypoints)
        return preview

    def _init(self, schedule: PhaseSchedule, waypoints: NDArray) -> None:
        xi_ref_0, xi_ref_T = schedule.backward_iteration(waypoints)
        v_ref_0 = waypoints[:-1]  # eq. (13)
        v_ref_T = waypoints[1:]  # eq. (14)
        dv = v_ref_T - v_ref_0
        # eq. (10) regrouped: ξ(t) = v_ref_0 + p(t) Δv + γ(t) r, r = ξ_ref_T − v_ref_0 − p_T Δv
        # with p = σ, p_T = σ_T (closed form) or p = β, p_T = 0 (module docstring)
        r = xi_ref_T - v_ref_0 - schedule._p_T[:, None] * dv
        self.__dict__.update(
            _schedule=schedule,
            _waypoints=waypoints,
            _xi_ref_0=xi_ref_0,
            _xi_ref_T=xi_ref_T,
            _v_ref_0=v_ref_0,
            _dv=_read_only(dv),
            _r=_read_only(r),
            _v0_list=[tuple(row) for row in v_ref_0.tolist()],
            _dv_list=[tuple(row) for row in dv.tolist()],
            _r_list=[tuple(row) for row in r.tolist()],
        )

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError(f"Preview is immutable; use with_waypoints() (tried to set {name})")

    def __repr__(self) -> str:
        s = self._schedule
        return (
            f"Preview(n_wp={s.n_waypoints}, n_phases={s.n_phases}, duration={s.duration:.3f} s, "
            f"b={s.b} s, order={s.order})"
        )

    # --- plain attributes -----------------------------------------------------------------------

    @property
    def waypoints(self) -> NDArray[np.float64]:
        """VRP waypoints v_wp (n_wp, 3), m."""
        return self._waypoints

    @property
    def durations(self) -> NDArray[np.float64]:
        """Transition phase durations T_φ (n_phi,), s."""
        return self._schedule.durations

    @property
    def b(self) -> float:
        """DCM time constant b (s), eq. (1)."""
        return self._schedule.b

    @property
    def order(self) -> int:
        """VRP polynomial order n_poly of Table I."""
        return self._schedule.order

    @property
    def n_phases(self) -> int:
        """Number of transition phases n_φ = n_wp − 1."""
        return self._schedule.n_phases

    @property
    def duration(self) -> float:
        """Total preview duration Σ T_φ (s)."""
        return self._schedule.duration

    @property
    def phase_start_times(self) -> NDArray[np.float64]:
        """Global start time (s) of each phase, (n_phi,)."""
        return self._schedule.phase_start_times

    @property
    def xi_ref_0(self) -> NDArray[np.float64]:
        """DCM reference start point of each phase (n_phi, 3), eq. (20)."""
        return self._xi_ref_0

    @property
    def xi_ref_T(self) -> NDArray[np.float64]:
        """DCM reference end point of each phase (n_phi, 3), eq. (21)."""
        return self._xi_ref_T

    @property
    def W_xi_ref_0(self) -> NDArray[np.float64]:
        """Scalar weights (n_phi, n_wp) of eq. (20): xi_ref_0 = W_xi_ref_0 @ waypoints."""
        return self._schedule.W_xi_ref_0

    @property
    def W_xi_ref_T(self) -> NDArray[np.float64]:
        """Scalar weights (n_phi, n_wp) of eq. (21): xi_ref_T = W_xi_ref_T @ waypoints."""
        return self._schedule.W_xi_ref_T

    @property
    def A_xi_ref_0(self) -> NDArray[np.float64]:
        """Matrix A_xi_ref_0 (3 n_phi, 3 n_wp) of eq. (20), = kron(W_xi_ref_0, I₃)."""
        return self._schedule.A_xi_ref_0

    @property
    def A_xi_ref_T(self) -> NDArray[np.float64]:
        """Matrix A_xi_ref_T (3 n_phi, 3 n_wp) of eq. (21), = kron(W_xi_ref_T, I₃)."""
        return self._schedule.A_xi_ref_T

    # --- evaluation -------------------------------------------------------------------------------

    def phase_at(self, t: float | ArrayLike) -> tuple[int, float] | tuple[NDArray, NDArray]:
        """0-based phase index φ and local time t_φ (s) of global time t (eq. 5's t_φ).

        At a phase boundary the later phase is returned, except at t = duration (last phase,
        t_φ = T_last). Vectorised: a 1-D array gives (int array, float array).
        """
        t = _as_time(t)
        if isinstance(t, float):
            return self._schedule.locate(t)
        return self._schedule.locate_array(t)

    def vrp(self, t: float | ArrayLike) -> NDArray[np.float64]:
        """VRP reference v_ref(t) (m), eq. (5) with eqs. (11), (12)."""
        t = _as_time(t)
        s = self._schedule
        if isinstance(t, float):
            return np.array(self._vrp_at(*s.locate(t)))
        phi, t_phi = s.locate_array(t)
        f = np.polynomial.polynomial.polyval(t_phi / s.durations[phi], s.f_coefficients)
        return self._v_ref_0[phi] + f[:, None] * self._dv[phi]

    def vrp_velocity(self, t: float | ArrayLike) -> NDArray[np.float64]:
        """VRP reference velocity (m/s): ḟ(t) (v_ref_T − v_ref_0), time derivative of eq. (5)."""
        t = _as_time(t)
        s = self._schedule
        if isinstance(t, float):
            return np.array(self._vrp_velocity_at(*s.locate(t)))
        phi, t_phi = s.locate_array(t)
        T = s.durations[phi]
        f_dot = np.polynomial.polynomial.polyval(t_phi / T, s.f_dot_coefficients) / T
        return f_dot[:, None] * self._dv[phi]

    def dcm(self, t: float | ArrayLike) -> NDArray[np.float64]:
        """DCM reference ξ_ref(t) (m), eq. (10) with ξ_ref_T from eq. (21) (equivalently 22/23)."""
        t = _as_time(t)
        s = self._schedule
        if isinstance(t, float):
            return np.array(self._dcm_at(*s.locate(t)))
        phi, t_phi = s.locate_array(t)
        T = s.durations[phi]
        sig = s.sample_p(phi, t_phi, T)
        g = np.exp((t_phi - T) / s.b)
        return self._v_ref_0[phi] + sig[:, None] * self._dv[phi] + g[:, None] * self._r[phi]

    def references(self, t: float) -> tuple[Triple, Triple, Triple]:
        """v_ref(t), ξ_ref(t) and v̇_ref(t) at one global time t (s) as float triples, with one
        phase lookup: what a controller reads every tick, the same numbers as :meth:`vrp`,
        :meth:`dcm` and :meth:`vrp_velocity`."""
        phi, t_phi = self._schedule.locate(float(t))
        return (
            self._vrp_at(phi, t_phi),
            self._dcm_at(phi, t_phi),
            self._vrp_velocity_at(phi, t_phi),
        )

    # the scalar path, per component in floats (3-vectors: numpy's per-call overhead would be
    # most of the cost), at phase φ and local time t_φ

    def _vrp_at(self, phi: int, t_phi: float) -> Triple:
        """Eq. (5): v_ref_0 + f(t) Δv."""
        s = self._schedule
        f = _horner(s._f, t_phi / s._T[phi])
        v0, dv = self._v0_list[phi], self._dv_list[phi]
        return (v0[0] + f * dv[0], v0[1] + f * dv[1], v0[2] + f * dv[2])

    def _vrp_velocity_at(self, phi: int, t_phi: float) -> Triple:
        """ḟ(t) Δv, the time derivative of eq. (5)."""
        s = self._schedule
        T = s._T[phi]
        f_dot = _horner(s._f_dot, t_phi / T) / T
        dv = self._dv_list[phi]
        return (f_dot * dv[0], f_dot * dv[1], f_dot * dv[2])

    def _dcm_at(self, phi: int, t_phi: float) -> Triple:
        """Eq. (10) regrouped: v_ref_0 + p(t) Δv + γ(t) r (module docstring)."""
        s = self._schedule
        T = s._T[phi]
        x = (2.0 * t_phi - T) / T if s._centred[phi] else t_phi / T
        sig = _horner(s._p[phi], x)
        g = math.exp((t_phi - T) / s.b)
        v0, dv, r = self._v0_list[phi], self._dv_list[phi], self._r_list[phi]
        return (
            v0[0] + sig * dv[0] + g * r[0],
            v0[1] + sig * dv[1] + g * r[1],
            v0[2] + sig * dv[2] + g * r[2],
        )

    def dcm_velocity(self, t: float | ArrayLike) -> NDArray[np.float64]:
        """DCM reference velocity ξ̇_ref(t) (m/s): time derivative of eq. (10), = (ξ − v)/b (6)."""
        t = _as_time(t)
        s = self._schedule
        if isinstance(t, float):
            phi, t_phi = s.locate(t)
            T = s._T[phi]
            if s._centred[phi]:  # β̇ = (β − f) / b, eq. (6)
                sig = _horner(s._p[phi], (2.0 * t_phi - T) / T)
                sig_dot = (sig - _horner(s._f, t_phi / T)) / s.b
            else:
                sig_dot = _horner(s._p_dot[phi], t_phi / T) / T
            g = math.exp((t_phi - T) / s.b) / s.b
            dv, r = self._dv_list[phi], self._r_list[phi]
            return np.array(
                (sig_dot * dv[0] + g * r[0], sig_dot * dv[1] + g * r[1], sig_dot * dv[2] + g * r[2])
            )
        phi, t_phi = s.locate_array(t)
        T = s.durations[phi]
        sig_dot = s.sample_p_dot(phi, t_phi, T)
        g = np.exp((t_phi - T) / s.b) / s.b
        return sig_dot[:, None] * self._dv[phi] + g[:, None] * self._r[phi]

    def dcm_weights(self, t: float | ArrayLike) -> NDArray[np.float64]:
        """Scalar weights w (n_wp,) with ξ_ref(t) = w @ waypoints, eqs. (22), (23).

        A_xi_ref_φ(t) = kron(w, I₃) = α_φ(t) 3row(A_v_ref_0, φ) + β_φ(t) 3row(A_v_ref_T, φ)
        + γ_φ(t) 3row(A_xi_ref_T, φ). A float costs O(n_wp) (row of eq. 21 by backward
        iteration); a 1-D array of N times gives (N, n_wp) from the cached W_xi_ref_T.
        """
        t = _as_time(t)
        s = self._schedule
        if isinstance(t, float):
            phi, t_phi = s.locate(t)
            T = s._T[phi]
            x = (2.0 * t_phi - T) / T if s._centred[phi] else t_phi / T
            sig = _horner(s._p[phi], x)
            g = math.exp((t_phi - T) / s.b)
            beta = sig - g * s._p_T_list[phi]  # β_φ(t), eq. (10)
            w = g * s.xi_ref_T_row(phi)
            w[phi] += 1.0 - g - beta  # α_φ(t) = 1 − γ − β, eq. (10)
            w[phi + 1] += beta
            return w
        phi, t_phi = s.locate_array(t)
        T = s.durations[phi]
        g = np.exp((t_phi - T) / s.b)
        beta = s.sample_p(phi, t_phi, T) - g * s._p_T[phi]
        w = g[:, None] * s.W_xi_ref_T[phi]
        rows = np.arange(t.size)
        w[rows, phi] += 1.0 - g - beta
        w[rows, phi + 1] += beta
        return w

    def with_waypoints(self, waypoints: ArrayLike) -> Preview:
        """A new Preview with the same durations, b and order and new VRP waypoints.

        Reuses the timing data and any cached weight matrices (eqs. 20, 21 are linear in v_wp,
        cf. eqs. 27, 28); costs one O(n) backward iteration.
        """
        s = self._schedule
        return Preview._from_schedule(s, _check_waypoints(waypoints, s.n_phases))


def _check_waypoints(waypoints: ArrayLike, n_phases: int) -> NDArray[np.float64]:
    array = check_points(waypoints, "waypoints", (None, 3))
    n_wp = array.shape[0]
    if n_wp < 2:
        raise ValueError(
            f"waypoints has {n_wp} row(s): a preview needs at least 2 VRP waypoints (n_wp ≥ 2)"
        )
    if n_wp != n_phases + 1:
        raise ValueError(
            f"waypoints has {n_wp} rows but durations has {n_phases} entries: "
            "need exactly one phase duration between consecutive waypoints (n_phi = n_wp − 1)"
        )
    return array


def _as_time(t: float | ArrayLike) -> float | NDArray[np.float64]:
    """A Python float for scalar times, a float 1-D array otherwise."""
    if type(t) is float:
        return t
    if isinstance(t, (int, np.integer, np.floating)) and not isinstance(t, bool):
        return float(t)
    try:
        array = np.asarray(t, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(f"t = {t!r}: time must be a float or a 1-D array of floats (s)") from error
    if array.ndim == 0:
        return float(array)
    if array.ndim != 1:
        raise ValueError(f"t has shape {array.shape}: time must be a float or a 1-D array (s)")
    return array
