"""Step timing for push recovery (issue 11): the phase durations as a recovery variable.

The closed-form preview makes the DCM an explicit function of the phase durations: with order 0
per phase, ξ(T) = v + e^{T/b}(ξ_0 − v) (eqs. 5, 10), so the time a footstep takes to land is a
leverage as strong as where it lands.  A push towards the stance foot cannot be caught by the
swinging foot (it may not cross the stance leg); the foot after it can, but only 1–1.5 s later,
while the error grows e^{t/b}.  Landing the swinging foot in place early, waiting in double
support while the CoP on the old stance foot brings the DCM back, and a short swing for the
stepping-out foot recover far more (``dcmviz.recovery``, capacity).

This module only builds and compares timings; the walker (``multi_step_timing``) picks among
:func:`timing_candidates` the one whose recovery QP leaves the smallest CoP shortfall, and
whose supports until the footstep after next bears the weight can bring ξ onto that footstep
(:func:`capture_shortfall`, the reachable DCM interval of :func:`reachable_dcm`), and moves
the walked plan's durations towards it at most ``RATE`` s per s, so ξ_ref, ξ_adj and the VRP
change continuously (a kink, never a jump) and the swing foot is re-timed from its present state
(:meth:`~dcmviz.gait.swing.SwingTrajectory.retime`).  Limits: a single support lasts
``SS_SCALE`` of its nominal duration (at least ``MIN_SS_S``) and ends at least
``MIN_REMAINING_S`` from now; a double support ``DS_SCALE`` of its nominal duration (at least
``MIN_DS_S``, and also not ending sooner than ``MIN_REMAINING_S`` from now).  Phases already over are never changed.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np

from dcmviz.dcm import Preview
from dcmviz.dcm.preview import PhaseSchedule
from dcmviz.gait.plan import GaitPlan

# single support: nominal, short (the stepping-out foot hurries), shortest (0.35 s of a 0.7 s
# single support: the foot that must land before the other can step out lands as soon as the
# walk's swings allow, as in the swing bound's walks, dcmviz.sweep.bounds.swing_walk)
SS_SCALE = (1.0, 0.6, 0.5)
# double support: nominal, short (the weight moves sooner), long (the CoP brings ξ back)
DS_SCALE = (1.0, 0.5, 2.5, 5.0)
MIN_SS_S = 0.35  # s, shortest single support (the swing must still lift and place the foot)
MIN_DS_S = 0.1  # s, shortest double support (weight transfer)
MIN_REMAINING_S = 0.12  # s, a single support under way ends no sooner than this from now
FLOOR_GRID_S = 0.02  # s, the floors of a phase under way on a grid (candidates repeat)
RATE = 1.5  # s per s: how fast a duration moves towards the chosen one
PHASES = 3  # the present phase and the next two may be re-timed (plan mode)


def dcm_after(xi0: np.ndarray, v: np.ndarray, duration_s: float, b: float) -> np.ndarray:
    """ξ(T) = v + e^{T/b}(ξ_0 − v): the DCM after a phase of constant VRP v (order 0, eq. 5)."""
    return np.asarray(v, float) + math.exp(duration_s / b) * (np.asarray(xi0, float) - v)


_SCHEDULES: dict[tuple, PhaseSchedule] = {}  # the timing part of a preview, per durations


def retimed(plan: GaitPlan, durations: np.ndarray) -> GaitPlan:
    """The same plan (waypoints, footsteps, schedule) with new phase durations (s).

    The waypoint-independent part of the preview (``PhaseSchedule``, eq. 15) is kept for the
    last few hundred timings: the candidates repeat from one comparison to the next."""
    if np.array_equal(durations, plan.preview.durations):
        return plan
    key = (plan.b, plan.order, np.asarray(durations, float).tobytes())
    schedule = _SCHEDULES.get(key)
    if schedule is None:
        if len(_SCHEDULES) > 512:
            _SCHEDULES.clear()
        schedule = _SCHEDULES[key] = PhaseSchedule(durations, plan.b, plan.order)
    preview = Preview._from_schedule(schedule, np.asarray(plan.preview.waypoints))
    return dataclasses.replace(plan, preview=preview)


def nominal_duration(plan: GaitPlan, phase: int) -> float:
    """The preset's duration of a phase (ss/ds), or the plan's own for start/stop phases."""
    kind = plan.phase_kind[phase]
    if kind == "ss":
        return plan.timing.t_ss
    if kind == "ds":
        return plan.timing.t_ds
    return float(plan.preview.durations[phase])


def timing_candidates(plan: GaitPlan, local: float, phases: int = PHASES) -> list[np.ndarray]:
    """Durations (the whole plan's) to compare: the present phase (local time ``local``) and the
    next ``phases − 1`` ss/ds phases take each of their scales (nominal first)."""
    durations = plan.preview.durations
    phase, t_phase = plan.preview.phase_at(local)
    phase = int(phase)
    options: list[tuple[int, list[float]]] = []
    for p in range(phase, min(phase + phases, len(durations))):
        kind = plan.phase_kind[p]
        if kind not in ("ss", "ds"):
            break
        nominal = nominal_duration(plan, p)
        if kind == "ss":
            values = [max(s * nominal, MIN_SS_S) for s in SS_SCALE]
        else:
            values = [max(s * nominal, MIN_DS_S) for s in DS_SCALE]
        if p == phase:  # under way: ends no sooner than MIN_REMAINING_S from now (a phase
            # that ends sooner anyway is not lengthened for it)
            floor = float(t_phase) + MIN_REMAINING_S
            floor = min(math.ceil(floor / FLOOR_GRID_S) * FLOOR_GRID_S, float(durations[p]))
            values = [max(v, floor) for v in values]
        options.append((p, list(dict.fromkeys(round(v, 9) for v in values))))
    if not options:
        return [durations.copy()]
    out = []
    for combo in itertools.product(*(vals for _, vals in options)):
        d = durations.copy()
        for (p, _), value in zip(options, combo, strict=True):
            d[p] = value
        out.append(d)
    return out


def towards(current: np.ndarray, target: np.ndarray, max_change_s: float) -> np.ndarray:
    """``current`` durations moved towards ``target`` by at most ``max_change_s`` each."""
    return current + np.clip(target - current, -max_change_s, max_change_s)


def reachable_dcm(
    xi0: np.ndarray, segments: list[tuple[float, np.ndarray, np.ndarray]], b: float
) -> tuple[np.ndarray, np.ndarray]:
    """Per axis, the interval of DCMs reachable after ``segments`` (duration s, CoP box lo, hi):
    ξ(T) = e^{T/b} ξ_0 + (1 − e^{T/b}) v (eq. 5, order 0) is monotone in ξ_0 and in v, so the
    extremes come from the interval's ends and the box's opposite edges, phase after phase."""
    lo = np.asarray(xi0, float).copy()
    hi = lo.copy()
    for duration, box_lo, box_hi in segments:
        if duration <= 0.0:
            continue
        e = math.exp(duration / b)
        lo, hi = e * lo + (1.0 - e) * box_hi, e * hi + (1.0 - e) * box_lo
    return lo, hi


def capture_shortfall(
    xi0: np.ndarray,
    segments: list[tuple[float, np.ndarray, np.ndarray]],
    region: tuple[np.ndarray, np.ndarray],
    b: float,
) -> np.ndarray:
    """How far (per axis, m) the DCMs reachable after ``segments`` stay from ``region`` (lo, hi):
    0 when some CoP inside each phase's support brings ξ into the region (capturable there)."""
    lo, hi = reachable_dcm(xi0, segments, b)
    r_lo, r_hi = (np.asarray(x, float) for x in region)
    return np.maximum(np.maximum(lo - r_hi, r_lo - hi), 0.0)
