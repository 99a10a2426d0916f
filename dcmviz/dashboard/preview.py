"""Sampled preview of a gait plan: what the 3D scene and the Fig. 1a plots draw.

Pure numpy over the closed-form :class:`~dcmviz.dcm.Preview` (eqs. 13–23); no viser here, so it
is cheap to test and to compute off the simulation thread.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dcmviz.gait import GaitPlan
from dcmviz.robots import RobotSpec
from dcmviz.robots.geometry import sole_corners

SAMPLES_PER_PHASE = 24

# phase kind -> RGB (0-255); the same colours label the 3D VRP trajectory and the legend
PHASE_COLORS: dict[str, tuple[int, int, int]] = {
    "start_a": (120, 120, 140),
    "start_b": (90, 140, 200),
    "ss": (240, 140, 30),
    "ds": (40, 170, 90),
    "stop": (150, 90, 200),
}


@dataclass(frozen=True)
class Sole:
    """A footstep drawn as its support rectangle."""

    side: str
    position: np.ndarray  # (3,) sole centre, m
    yaw: float  # rad
    index: int  # index into plan.steps, -1 for the standing feet at t = 0

    def corners(self, length: float, width: float) -> np.ndarray:
        """(4, 3) rectangle corners, counter-clockwise."""
        xy = sole_corners(self.position, self.yaw, length, width)
        return np.column_stack([xy, np.full(4, self.position[2])])


@dataclass(frozen=True)
class PreviewData:
    """Everything the preview draws, sampled once per plan."""

    t: np.ndarray  # (N,) s, global time (plan.t0 + plan-local time)
    vrp: np.ndarray  # (N, 3) m, eq. (13)
    dcm: np.ndarray  # (N, 3) m, eq. (16)
    sample_kind: tuple[str, ...]  # (N,) phase kind of each sample
    waypoints: np.ndarray  # (n_wp, 3) VRP waypoints
    soles: tuple[Sole, ...]
    foot_length: float
    foot_width: float
    dz_vrp: float  # m, g b²

    def vrp_segments(self) -> tuple[np.ndarray, np.ndarray]:
        """Line segments (N-1, 2, 3) of the VRP trajectory and their colours (N-1, 2, 3)."""
        pts = np.stack([self.vrp[:-1], self.vrp[1:]], axis=1)
        rgb = np.array([PHASE_COLORS.get(k, (200, 200, 200)) for k in self.sample_kind[:-1]])
        return pts, np.repeat(rgb[:, None, :], 2, axis=1).astype(np.uint8)


def sample_times(plan: GaitPlan, per_phase: int = SAMPLES_PER_PHASE) -> tuple[np.ndarray, list]:
    """Sample times (plan-local, s) with ``per_phase`` samples in every phase, and their kinds."""
    starts = np.asarray(plan.preview.phase_start_times, dtype=float)
    durs = np.asarray(plan.preview.durations, dtype=float)
    frac = np.linspace(0.0, 1.0, per_phase, endpoint=False)
    t = (starts[:, None] + durs[:, None] * frac[None, :]).ravel()
    kinds = [k for k in plan.phase_kind for _ in range(per_phase)]
    t = np.append(t, plan.preview.duration)
    kinds.append(plan.phase_kind[-1])
    return t, kinds


def preview_data(plan: GaitPlan, spec: RobotSpec) -> PreviewData:
    """Sample the plan's VRP (eq. 13) and DCM (eq. 16) and collect its soles."""
    t, kinds = sample_times(plan)
    soles = [
        Sole(f.side, np.asarray(f.position, float), f.yaw, -1) for f in plan.start_feet.values()
    ]
    soles += [
        Sole(f.side, np.asarray(f.position, float), f.yaw, i) for i, f in enumerate(plan.steps)
    ]
    return PreviewData(
        t=plan.t0 + t,
        vrp=plan.preview.vrp(t),
        dcm=plan.preview.dcm(t),
        sample_kind=tuple(kinds),
        waypoints=np.asarray(plan.preview.waypoints),
        soles=tuple(soles),
        foot_length=spec.foot_length_m,
        foot_width=spec.foot_width_m,
        dz_vrp=plan.dz_vrp,
    )
