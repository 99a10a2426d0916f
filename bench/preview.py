"""Preview cost: O(n) backward iteration vs the dense matrices of eqs. (16)–(23), one run.

    PYTHONPATH=. python3 bench/preview.py

Realistic walking plans: feet alternating ±0.085 m, 0.2 m steps, single support 0.7 s (VRP
heel → toe), double support 0.2 s, 1 s start and stop phases, b = 0.3 s, Δz = g b², order 5,
continuity D1–D3 (eq. 26). Prints figures and ratios; asserts nothing.
"""

from __future__ import annotations

import time
import timeit
from collections.abc import Callable

import numpy as np

from dcmviz import GRAVITY
from dcmviz.dcm import Preview, continuity_waypoints
from dcmviz.dcm.interpolation import (
    CLOSED_FORM_ERROR_BOUND,
    alpha_beta,
    alpha_beta_0,
    f,
    gamma,
    gamma_0,
)

B = 0.3
ORDER = 5
T_SS, T_DS, T_START, T_STOP = 0.7, 0.2, 1.0, 1.0
STEP_LENGTH, HALF_WIDTH, HEEL_TO_TOE = 0.2, 0.085, 0.04


def walking_plan(n_steps: int) -> tuple[np.ndarray, np.ndarray]:
    """VRP waypoints (n_wp, 3) and durations (n_wp − 1,) of stand → n_steps → stand."""
    dz = GRAVITY * B**2
    # stance feet: the first stance foot is the right one (left swings first), then alternate
    feet = [
        np.array([STEP_LENGTH * k, -HALF_WIDTH if k % 2 == 0 else HALF_WIDTH, dz])
        for k in range(n_steps + 1)
    ]
    v_uc = []  # heel and toe of every stance foot but the first one's heel (D2 sets v_wp,2)
    for k, foot in enumerate(feet):
        heel, toe = foot - [HEEL_TO_TOE / 2, 0, 0], foot + [HEEL_TO_TOE / 2, 0, 0]
        v_uc.extend([toe] if k == 0 else [heel, toe])
    v_uc = v_uc[:-1]  # the last stance foot: feet come together, final standing point
    durations = [T_START] + [T_SS, T_DS] * n_steps + [T_STOP]
    v_stand_ini = np.array([0.0, 0.0, dz])
    v_stand_end = np.array([STEP_LENGTH * (n_steps - 0.5), 0.0, dz])  # between the last feet
    v_uc = np.array(v_uc)[: len(durations) - 2]
    waypoints = continuity_waypoints(v_stand_ini, v_uc, v_stand_end, durations, B, ORDER)
    return waypoints, np.array(durations)


class DensePreview:
    """Eqs. (13)–(23) as printed: 3n × 3n matrices, np.linalg.inv, dense 3row evaluation."""

    def __init__(self, waypoints: np.ndarray, durations: np.ndarray, b: float, order: int):
        n_phi, n_wp = len(durations), len(durations) + 1
        I3 = np.eye(3)
        self.A_v_ref_0 = np.kron(np.eye(n_phi, n_wp), I3)  # (13)
        self.A_v_ref_T = np.kron(np.eye(n_phi, n_wp, k=1), I3)  # (14)
        A_gamma = np.kron(np.diag(gamma_0(durations, b)), I3)  # (16)
        alpha_0, beta_0 = alpha_beta_0(durations, b, order)
        A_alpha_beta = np.kron(
            np.diag(alpha_0) @ np.eye(n_phi, n_wp) + np.diag(beta_0) @ np.eye(n_phi, n_wp, k=1),
            I3,
        )
        A_BWI = np.kron(np.eye(n_phi, k=1), I3)  # (19)
        A_TC = np.zeros((3 * n_phi, 3 * n_wp))
        A_TC[-3:, -3:] = I3
        eye = np.eye(3 * n_phi)
        self.A_xi_ref_0 = np.linalg.inv(eye - A_gamma @ A_BWI) @ (A_alpha_beta + A_gamma @ A_TC)
        self.A_xi_ref_T = np.linalg.inv(eye - A_BWI @ A_gamma) @ (A_TC + A_BWI @ A_alpha_beta)
        self.v_wp = waypoints.ravel()
        self.durations, self.b, self.order = durations, b, order
        self.starts = np.concatenate(([0.0], np.cumsum(durations)[:-1]))

    def sample(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """VRP (eq. 5 as 3row matrices) and DCM (eqs. 22, 23) at times t, phase by phase."""
        phases = np.clip(np.searchsorted(self.starts, t, side="right") - 1, 0, None)
        vrp, dcm = np.empty((t.size, 3)), np.empty((t.size, 3))
        for phi in np.unique(phases):
            k = phases == phi
            t_phi, T = t[k] - self.starts[phi], self.durations[phi]
            rows = slice(3 * phi, 3 * phi + 3)  # 3row(·, φ)
            R0, RT, RxiT = self.A_v_ref_0[rows], self.A_v_ref_T[rows], self.A_xi_ref_T[rows]
            fs = f(t_phi, T, self.order)[:, None, None]
            vrp[k] = ((1 - fs) * R0 + fs * RT) @ self.v_wp
            a, be = alpha_beta(t_phi, T, self.b, self.order)
            a, be = a[:, None, None], be[:, None, None]
            g = gamma(t_phi, T, self.b)[:, None, None]
            dcm[k] = (a * R0 + be * RT + g * RxiT) @ self.v_wp  # (23), then (22)
        return vrp, dcm


def best_time(function: Callable[[], object], repeats: int) -> float:
    """Best wall time of ``repeats`` calls, s."""
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    print(f"Preview benchmark: order {ORDER}, b = {B} s, sampling at 1 kHz (VRP + DCM)\n")
    header = (
        f"{'steps':>5} {'phases':>6} {'T [s]':>6} | {'build O(n)':>11} {'sample O(n)':>11} | "
        f"{'build dense':>11} {'sample dense':>12} | {'build ×':>8} {'sample ×':>8} "
        f"{'max |Δξ| [m]':>12}"
    )
    print(header)
    print("-" * len(header))
    for n_steps in (5, 20, 50, 200):
        waypoints, durations = walking_plan(n_steps)
        p = Preview(waypoints, durations, B, ORDER)
        t = np.arange(0.0, p.duration, 1e-3)
        repeats = 20 if n_steps <= 50 else 5
        build = best_time(lambda w=waypoints, d=durations: Preview(w, d, B, ORDER), repeats)
        sample = best_time(lambda p=p, t=t: (p.vrp(t), p.dcm(t)), repeats)
        dense_repeats = 5 if n_steps <= 50 else 1
        build_dense = best_time(
            lambda w=waypoints, d=durations: DensePreview(w, d, B, ORDER), dense_repeats
        )
        dense = DensePreview(waypoints, durations, B, ORDER)
        sample_dense = best_time(lambda dense=dense, t=t: dense.sample(t), dense_repeats)
        error = np.abs(dense.sample(t)[1] - p.dcm(t)).max()
        print(
            f"{n_steps:>5} {p.n_phases:>6} {p.duration:>6.1f} | {build * 1e3:>8.3f} ms "
            f"{sample * 1e3:>8.3f} ms | {build_dense * 1e3:>8.2f} ms {sample_dense * 1e3:>9.1f} ms"
            f" | {build_dense / build:>7.0f}× {sample_dense / sample:>7.0f}× {error:>12.1e}"
        )

    waypoints, durations = walking_plan(20)
    p = Preview(waypoints, durations, B, ORDER)
    t_100 = np.arange(0.0, p.duration, 1e-2)

    def build_and_sample() -> None:
        q = Preview(waypoints, durations, B, ORDER)
        q.vrp(t_100)
        q.dcm(t_100)

    total = best_time(build_and_sample, 50)
    print(
        f"\n20 steps ({p.duration:.1f} s): build + sample at 100 Hz ({t_100.size} samples): "
        f"{total * 1e3:.3f} ms"
    )

    number = 20000
    t0 = 0.37 * p.duration
    tick = min(timeit.repeat(lambda: (p.vrp(t0), p.dcm(t0)), number=number, repeat=7)) / number
    weights = min(timeit.repeat(lambda: p.dcm_weights(t0), number=number, repeat=5)) / number
    new = waypoints + 0.01
    rebuild = min(timeit.repeat(lambda: p.with_waypoints(new), number=2000, repeat=5)) / 2000
    print(f"per tick, one scalar time: p.vrp(t) + p.dcm(t)      {tick * 1e6:7.2f} µs")
    print(
        f"per tick, one scalar time: p.dcm_weights(t) (n_wp={len(waypoints)}) {weights * 1e6:7.2f} µs"
    )
    print(f"p.with_waypoints(new) (20 steps)                    {rebuild * 1e6:7.2f} µs")

    # Short phases (T/b below the closed-form threshold, 1.94 for order 5) are sampled by the
    # series of β (about 15–21 terms) instead of σ (6 terms) and one exponential.
    n_phi, rng = 200, np.random.default_rng(0)
    t = rng.uniform(0.0, 1.0, 100_000)
    print(f"\nper sample, {t.size} random times, {n_phi} phases, b = {B} s (VRP + DCM):")
    for T in (1.0, 0.5, 0.1, 0.001):
        q = Preview(rng.uniform(-1, 1, (n_phi + 1, 3)), np.full(n_phi, T), B, ORDER)
        ts = t * q.duration
        per_sample = best_time(lambda q=q, ts=ts: (q.vrp(ts), q.dcm(ts)), 10) / ts.size
        path = "closed form" if q._schedule.closed_form.all() else "series"
        print(f"  T = {T:5.3f} s (T/b = {T / B:6.3f}, {path:>11}): {per_sample * 1e9:6.1f} ns")
    print(f"  (closed form where closed_form_error_bound ≤ {CLOSED_FORM_ERROR_BOUND:g})")


if __name__ == "__main__":
    main()
