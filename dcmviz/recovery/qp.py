"""The multi-step recovery QP: the paper's linear maps, several footsteps, one small QP (issue 11).

The paper adjusts the next footstep only (eqs. 27–35) and names the general case future work
("each element of this VRP adjustment vector could be used independently … formulated as an
optimization problem").  Here the next ``n`` modifiable footsteps j = k, k+1, … each get their
own horizontal Δv_j, and every footstep's leverage is the paper's own: moving footstep j by Δv_j
moves the DCM reference at j's adjustment instant (the start of its first affected phase, or the
end of the plan for the closing step) by c_j Δv_j, with c_j = 3row(A_ξref,0, φ_fa,j) S_adj,j
(eq. 28; c_j = 1/A_adj,j of eq. 32).  The DCM error ξ̃ (assumed to persist, eq. 31) is shared out
by

    minimise   Σ_j ω_j |Δv_j|²  +  ρ |ξ̃ − Σ_j c_j Δv_j|²
    subject to every footstep inside the reach of the one before it (adjusted), in that foot's
               frame (|Δx| ≤ max length, min width ≤ lateral ≤ max width), and |Δv_j| ≤ the
               adjustment limit (per axis),

with ω_j = exp((t_j − t_k)/b) growing with how much later than the next footstep's instant t_k
footstep j's instant t_j lies (a near footstep is cheap to move, a far one is kept near its
plan), and ρ large (the condition
of eq. 31 holds whenever the constraints allow it).  A footstep whose swing is frozen is a
constant, not a variable.  The solution is continuous in ξ̃ and in time (a strictly convex QP
with continuous data), and by the principle of optimality the remaining footsteps' optimum does
not change when one of them is frozen or committed at its touchdown: the adapted reference
ξ_adj = ξ_ref + Σ_j (w(t)·s_j) Δv_j (eqs. 33–35) stays smooth.  With the constraints inactive
the solution is the weighted least-squares one, which the tests check against a dense solve of
eq. (28).

Honest leverages (``capacity``).  The condition above takes ξ̃ to persist until each footstep's
own instant (eq. 31), which is optimistic for a footstep that lands late: the DCM error grows as
e^{t/b} where the CoP (VRP) saturates, and the footstep after the next one lands 1–1.5 s later.
What the footsteps must absorb now is read off the same linear maps at the present time:
ξ_adj(t) = ξ_ref(t) + Σ_j a_j(t) Δv_j with a_j(t) = w(t)·s_j (eqs. 22, 33–35), so the tracking
error ε = ξ − ξ_adj = ξ̃ − Σ_j a_j(t) Δv_j is what the CoP must remove.  A CoP offset δ held for
the time τ left on the present support removes ε = (1 − e^{−τ/b}) δ (order 0 per phase:
ε(τ) = δ + e^{τ/b}(ε − δ) = 0), and v_ref + δ must lie in the support polygon: the constraint
``capacity`` is lo ≤ R ε ≤ hi (R the polygon's axes), softened by a slack σ with weight
SLACK_WEIGHT ≫ ρ.  With it the QP asks the later footsteps for what the growing error really
needs (capture-region reasoning: footsteps and CoP together must capture the DCM), and its
slack says how far from capturable a timing leaves the robot (``dcmviz.gait.timing``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import daqp
import numpy as np

from dcmviz.robots import RobotSpec
from dcmviz.robots.feet import SIDE_SIGN, Footstep

CONDITION_WEIGHT = 1e4  # ρ: how strongly Σ c_j Δv_j = ξ̃ (eq. 31) is asked for
SLACK_WEIGHT = 1e7  # weight of σ, the part of ε the CoP cannot remove (``capacity``)
_INF = 1e30
EYE2 = np.eye(2)  # read-only: a capacity's axes when they are the world's
EYE2.flags.writeable = False


@dataclass(frozen=True)
class Capacity:
    """What the CoP can still remove: lo ≤ axes @ ε ≤ hi for ε = ξ − ξ_adj (m)."""

    axes: np.ndarray  # (2, 2) rows: the support polygon's axes in the world frame
    lo: np.ndarray  # (2,)
    hi: np.ndarray  # (2,)


@dataclass(frozen=True)
class Solution:
    """The QP's answer: Δv_j per candidate and σ, the CoP's shortfall (0: capturable)."""

    dv: list[np.ndarray]
    slack: np.ndarray  # (2,) m, in the capacity's axes
    step_cost: float  # Σ ω_j |Δv_j|² (m²)


@dataclass(frozen=True)
class Candidate:
    """One footstep the QP may move."""

    nominal: Footstep  # where the plan has it
    leverage: float  # c_j = 1/A_adj,j: DCM reference change at its instant per metre moved
    lead_time_s: float  # t_j − t: how far in the future its adjustment instant lies
    fixed: np.ndarray | None = None  # (2,) Δv of a frozen footstep (not a variable)
    box: tuple[np.ndarray, np.ndarray] | None = None  # (lo, hi) of Δv_xy: e.g. the tread's
    now_leverage: float = 0.0  # a_j(t): ξ_adj change now per metre moved (for ``capacity``)
    # a convex region A p ≤ b for the footstep in the frame of the one before it (p = (x,
    # lateral towards its own side)) replacing the reach box: a crossover (dcmviz.robots.crossover)
    region: tuple[np.ndarray, np.ndarray] | None = None


def weights(candidates: list[Candidate], b: float) -> np.ndarray:
    """ω_j = exp((t_j − t_0)/b): 1 for the next footstep, growing with how much later footstep
    j's adjustment instant t_j comes."""
    t0 = candidates[0].lead_time_s
    return np.array([math.exp(max(c.lead_time_s - t0, 0.0) / b) for c in candidates])


def solve(
    candidates: list[Candidate],
    stance: Footstep,
    xi_error: np.ndarray,
    spec: RobotSpec,
    max_adjustment: float,
    b: float,
    *,
    constrained: bool = True,
) -> list[np.ndarray]:
    """Δv_j (each (3,), z = 0) for the candidates, in order; ``stance`` is where the foot stands
    that candidate 0 steps from."""
    return solve_full(
        candidates, stance, xi_error, spec, max_adjustment, b, constrained=constrained
    ).dv


def solve_full(
    candidates: list[Candidate],
    stance: Footstep,
    xi_error: np.ndarray,
    spec: RobotSpec,
    max_adjustment: float,
    b: float,
    *,
    constrained: bool = True,
    capacity: Capacity | None = None,
    centre: np.ndarray | None = None,
) -> Solution:
    """:func:`solve` with the CoP's ``capacity`` (module docstring) and σ, the step cost;
    ``centre`` (2,), if given, chains the ±``max_adjustment`` boxes sideways: in the frame of
    the footstep before it (t forwards, n to its left), a footstep moves at most max forwards or
    backwards from its nominal place (|t·Δv_i| ≤ max, the box of the paper) and at most max
    sideways from where the footstep before it moved, |n·(Δv_i − Δv_{i−1})| ≤ max, Δv_{−1} =
    ``centre`` (how far the foot it steps from landed from its own nominal place).  So the
    sideways room is counted from where the feet are: a swinging foot moved in towards the
    stance foot no longer takes it from the footstep after it, and that footstep's box does not
    move when the swinging one lands (its centre goes from Δv_k to where footstep k landed).
    Forwards the box stays round the nominal place: chained there too, the footstep after a
    shortened one was let step back further, which Talos did not take (its 0.2 s backward push
    in the sweep, 50.8 → 47.3 N·s)."""
    free = [i for i, c in enumerate(candidates) if c.fixed is None]
    col = {i: 2 * j for j, i in enumerate(free)}
    n_dv = 2 * len(free)
    nx = n_dv + (2 if capacity is not None else 0)  # + σ
    e = np.asarray(xi_error, dtype=float)[:2].copy()
    eps0 = e.copy()  # ε = ξ̃ − Σ a_j Δv_j, the fixed part
    for c in candidates:
        if c.fixed is not None:
            e -= c.leverage * c.fixed
            eps0 -= c.now_leverage * c.fixed
    omega = weights(candidates, b)
    if nx == 0:
        return Solution([np.array([*c.fixed, 0.0]) for c in candidates], np.zeros(2), 0.0)
    lev = np.zeros((2, nx))  # Σ c_j Δv_j as a 2 × nx map
    H = np.zeros((nx, nx))
    for i in free:  # the 2 × 2 blocks 2 ω_i I and c_i I, written by their diagonals
        j = col[i]
        weight, leverage = 2.0 * omega[i], candidates[i].leverage
        H[j, j] += weight
        H[j + 1, j + 1] += weight
        lev[0, j] = lev[1, j + 1] = leverage
    H += 2.0 * CONDITION_WEIGHT * lev.T @ lev
    f = -2.0 * CONDITION_WEIGHT * lev.T @ e
    lo = np.full(nx, -max_adjustment)
    up = np.full(nx, max_adjustment)
    rows: list[np.ndarray] = []
    r_lo: list[float] = []
    r_up: list[float] = []
    if centre is not None:  # the lateral boxes chained (docstring), as rows in each frame
        before_dv: tuple[float, float] | None = tuple(np.asarray(centre, float)[:2].tolist())
        before_col: int | None = None
        previous = stance
        for i, c in enumerate(candidates):
            if c.fixed is not None:
                before_dv, before_col = (float(c.fixed[0]), float(c.fixed[1])), None
                previous = c.nominal
                continue
            j = col[i]
            cy, sy = math.cos(previous.yaw), math.sin(previous.yaw)
            lo[j : j + 2], up[j : j + 2] = -_INF, _INF
            row = np.zeros(nx)  # forwards: |t·Δv_i| ≤ max, round the nominal place
            row[j], row[j + 1] = cy, sy
            rows.append(row)
            r_lo.append(-max_adjustment)
            r_up.append(max_adjustment)
            row = np.zeros(nx)  # sideways: |n·(Δv_i − Δv_before)| ≤ max
            row[j], row[j + 1] = -sy, cy
            offset = 0.0
            if before_col is not None:
                row[before_col], row[before_col + 1] = sy, -cy
            else:
                offset = -sy * before_dv[0] + cy * before_dv[1]
            rows.append(row)
            r_lo.append(offset - max_adjustment)
            r_up.append(offset + max_adjustment)
            before_dv, before_col = None, j
            previous = c.nominal
    if capacity is not None:
        H[n_dv, n_dv] += 2.0 * SLACK_WEIGHT  # 2 S I on σ's block, by its diagonal
        H[n_dv + 1, n_dv + 1] += 2.0 * SLACK_WEIGHT
        lo[n_dv:], up[n_dv:] = -_INF, _INF
    for i in free:
        if candidates[i].box is not None:
            j = col[i]
            lo[j : j + 2] = np.maximum(lo[j : j + 2], candidates[i].box[0])
            up[j : j + 2] = np.minimum(up[j : j + 2], candidates[i].box[1])
            up[j : j + 2] = np.maximum(up[j : j + 2], lo[j : j + 2])
    if constrained:
        previous = stance
        previous_col: int | None = None
        previous_fixed = np.zeros(2)
        for i, c in enumerate(candidates):
            # the footstep in the frame of the one before it: R(ψ_prev)ᵀ (p_i − p_prev)
            cy, sy = math.cos(previous.yaw), math.sin(previous.yaw)
            axes = np.array([[cy, sy], [-sy, cy]])
            axes[1] *= SIDE_SIGN[c.nominal.side]  # lateral > 0 on the side of the swinging foot
            d0 = c.nominal.position[:2] - previous.position[:2] - previous_fixed
            if c.fixed is not None:
                d0 = d0 + c.fixed
            base = axes @ d0
            if c.region is not None:  # the crossover polygon: A (axes (d0 + Δv_i − Δv_prev)) ≤ b
                normals, bounds = c.region
                for normal, bound in zip(normals @ axes, bounds - normals @ base, strict=True):
                    row = np.zeros(nx)
                    if i in col:
                        row[col[i] : col[i] + 2] += normal
                    if previous_col is not None:
                        row[previous_col : previous_col + 2] -= normal
                    if row.any():
                        rows.append(row)
                        r_lo.append(-_INF)
                        r_up.append(float(bound))
                limits = ()
            else:
                limits = (
                    (-spec.max_step_length_m, spec.max_step_length_m),
                    (spec.min_step_width_m, spec.max_step_width_m),
                )
            if limits and (i in col or previous_col is not None):  # else both fixed: no rows
                base_list = base.tolist()
                for axis, (low, high) in enumerate(limits):
                    a0, a1 = axes[axis].tolist()
                    row = np.zeros(nx)  # 0 + a and 0 − a, entry by entry (a unit row)
                    if i in col:
                        j = col[i]
                        row[j], row[j + 1] = a0, a1
                    if previous_col is not None:
                        row[previous_col], row[previous_col + 1] = -a0, -a1
                    rows.append(row)
                    r_lo.append(low - base_list[axis])
                    r_up.append(high - base_list[axis])
            previous = c.nominal
            previous_col = col.get(i)
            previous_fixed = c.fixed if c.fixed is not None else np.zeros(2)
    if capacity is not None:
        # lo ≤ R (ε0 − Σ a_j Δv_j) − σ ≤ hi: the CoP removes the rest by the end of its support
        base = capacity.axes @ eps0
        for axis in range(2):
            a0, a1 = capacity.axes[axis].tolist()
            row = np.zeros(nx)
            for i in free:  # −a_i(t) × the axis, entry by entry
                j, a = col[i], -candidates[i].now_leverage
                row[j], row[j + 1] = a * a0, a * a1
            row[n_dv + axis] = -1.0
            rows.append(row)
            r_lo.append(capacity.lo[axis] - base[axis])
            r_up.append(capacity.hi[axis] - base[axis])
    A = np.array(rows) if rows else np.zeros((0, nx))
    bl = np.concatenate([lo, np.array(r_lo)])
    bu = np.concatenate([up, np.array(r_up)])
    sense = np.zeros(len(bl), dtype=np.int32)
    x, _, exitflag, _ = daqp.solve(H, f, A, bu, bl, sense)
    if exitflag not in (1, 2) or not math.isfinite(float(x.sum())):  # a NaN or inf anywhere
        x = np.zeros(nx)  # infeasible (a plan already out of reach): leave the footsteps alone
    out = []
    cost = 0.0
    xs = x.tolist()
    for i, c in enumerate(candidates):
        if c.fixed is not None:
            out.append(np.array([c.fixed[0], c.fixed[1], 0.0]))
        else:
            dx, dy = xs[col[i]], xs[col[i] + 1]
            out.append(np.array([dx, dy, 0.0]))
            cost += omega[i] * float(dx**2 + dy**2)
    slack = x[n_dv:].copy() if capacity is not None else np.zeros(2)
    if capacity is not None and exitflag not in (1, 2):
        slack = np.full(2, 1.0)  # unknown: as bad as it gets
    return Solution(out, slack, cost)


def least_squares(candidates: list[Candidate], xi_error: np.ndarray, b: float) -> list[np.ndarray]:
    """The unconstrained optimum in closed form (weighted least squares; for tests)."""
    e = np.asarray(xi_error, dtype=float)[:2].copy()
    for c in candidates:
        if c.fixed is not None:
            e -= c.leverage * c.fixed
    omega = weights(candidates, b)
    free = [i for i, c in enumerate(candidates) if c.fixed is None]
    # Δv_j = c_j/ω_j · λ with λ = ρ (e − Σ c_j Δv_j)  ⇒  λ = e / (1/ρ + Σ c_j²/ω_j)
    denom = 1.0 / CONDITION_WEIGHT + sum(candidates[i].leverage ** 2 / omega[i] for i in free)
    lam = e / denom
    out = []
    for i, c in enumerate(candidates):
        dv = c.fixed if c.fixed is not None else c.leverage / omega[i] * lam
        out.append(np.array([dv[0], dv[1], 0.0]))
    return out
