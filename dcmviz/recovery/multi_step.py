"""``multi_step``: the next footsteps share the DCM error through one small QP (:mod:`.qp`), their
present leverages bounded by what the CoP can still do (the capacity), and a commanded VRP outside
the support brought in keeping its lateral part first."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from dcmviz.gait.plan import GaitPlan
from dcmviz.gait.walk import Walk
from dcmviz.recovery import qp
from dcmviz.recovery.base import NO_ADJUSTMENT, Adjustment, RecoveryStrategy
from dcmviz.robots.feet import OTHER, SIDES, Footstep
from dcmviz.robots.geometry import convex_hull, project_to_polygon, sole_corners, soles_box

MULTI_STEPS = 3  # footsteps sharing the DCM error
CAPACITY_MARGIN_M = 0.01  # the recovery QP's CoP stays this far inside the soles ...
# ... or this share of the sole's half length (half width) if that is less: 1 cm of the G1's 3 cm
# half width credited its CoP with a third less than the sole gives, and under a 10 % pull its
# recovery QP moved the footsteps towards the pull where next_step kept them (it fell, next_step
# walked); the soles of Talos and Romeo (0.13, 0.12 m wide) keep the 1 cm
CAPACITY_MARGIN_SHARE = 0.2
CAPACITY_TIME_CONSTANTS = 1.0  # τ/b: the CoP is credited with removing ε within one b
SOLE_BOXES_KEPT = 64  # placements whose sole boxes are kept (a walk asks for a few at a time)
LATERAL_PRIORITY = 4.0  # a VRP outside the support keeps its lateral part first (shape_vrp)
PRIORITY_BLEND_M = 0.03  # ... blended in over this far beyond the outer foot


def capacity_margin(size_m: float) -> float:
    """How far (m) the recovery QP's CoP credit stays inside a sole of this length or width:
    CAPACITY_MARGIN_M, or CAPACITY_MARGIN_SHARE of the half size on a small sole."""
    return min(CAPACITY_MARGIN_M, CAPACITY_MARGIN_SHARE * 0.5 * size_m)


class MultiStep(RecoveryStrategy):
    """The next MULTI_STEPS modifiable footsteps share ξ̃ (:func:`.qp.solve_full`)."""

    name = "multi_step"

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.last_slack = 0.0  # m, the recovery QP's CoP shortfall at the last tick
        # (preview, phase, VRP at the phase's start, its travel, |travel|²): _transfer_progress
        self._transfer: tuple | None = None
        self._boxes: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}  # sole_box's, by placement
        self._kept_candidates: tuple | None = None  # _candidates' last answer and its key

    def __getstate__(self) -> dict:
        """A copy (Walker.copy, a pickled resume) starts with empty caches: they rebuild from
        the walk, and carrying them made every checkpoint copy up to SOLE_BOXES_KEPT boxes."""
        state = self.__dict__.copy()
        state["_boxes"], state["_kept_candidates"] = {}, None
        return state

    def adjust(
        self, walk: Walk, t: float, local: float, xi_error: np.ndarray, max_adjustment: float
    ) -> Adjustment:
        """Δξ_adj with the next footsteps sharing ξ̃ through one QP, their present leverages
        bounded by what the CoP can still do (:meth:`capacity`)."""
        plan = walk.plan
        k = plan.next_modifiable_step(t)
        if k is None:
            return NO_ADJUSTMENT
        solution, candidates = self.solve(walk, plan, t, local, k, xi_error, max_adjustment)
        self.last_slack = float(np.linalg.norm(solution.slack))
        return self.adjustment(walk, plan, k, candidates, solution.dv)

    @staticmethod
    def adjustment(
        walk: Walk, plan: GaitPlan, k: int, candidates: list[qp.Candidate], dvs: list[np.ndarray]
    ) -> Adjustment:
        """The walker's answer for footsteps k, k+1, … moved by ``dvs``: Δξ_adj = Σ_j (w(t)·s_j)
        Δv_j (eq. 34; w(t)·s_j is each candidate's ``now_leverage``, read once by :meth:`solve`),
        where footsteps k and k+1 land, and whether the swinging foot heads for footstep k."""
        delta = np.zeros(3)
        for candidate, dv in zip(candidates, dvs, strict=True):
            delta = delta + candidate.now_leverage * dv
        target = plan.steps[k].position + dvs[0]
        retarget = walk.swing_step == k and candidates[0].fixed is None
        following = (k + 1, plan.steps[k + 1].position + dvs[1]) if len(dvs) > 1 else None
        return Adjustment(delta, (k, target), following, retarget)

    def solve(
        self,
        walk: Walk,
        plan: GaitPlan,
        t: float,
        local: float,
        k: int,
        xi_error: np.ndarray,
        max_adjustment: float,
        region: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[qp.Solution, list[qp.Candidate]]:
        """The recovery QP for ``plan`` (the walked one or a re-timed candidate) from footstep k;
        ``region`` (A, b), if given, replaces footstep k's reach box (a crossover)."""
        candidates, capacity = self._candidates(walk, plan, t, local, k)
        if region is not None:
            candidates = [dataclasses.replace(candidates[0], region=region), *candidates[1:]]
        stance = plan.stance_for(k)
        solution = qp.solve_full(
            candidates, stance, xi_error, self.spec, max_adjustment, self.b,
            capacity=capacity, centre=self.carried(walk, stance),
        )  # fmt: skip
        return solution, candidates

    @staticmethod
    def carried(walk: Walk, stance: Footstep) -> np.ndarray:
        """Where footstep k's adjustment box is centred (:func:`.qp.solve_full`'s ``centre``, the
        later boxes chained to it): as far from its nominal place as the foot it steps from
        landed from its own (``StepRecord.adjustment``; 0 before any landing).  The box bounds
        how far a footstep moves from where the walk would have put it *from that foot*: after
        the swinging foot was moved 13 cm in towards the stance foot (Alexander, the paper's
        push pair at 1.5x, a 0.24 m stance), a box round the next footstep's nominal place kept
        it 0.41 m from that foot where the robot steps 0.60 m wide, and ξ ran past it."""
        records = walk.records
        if not records or records[-1].side != stance.side:
            return np.zeros(2)
        return np.asarray(records[-1].adjustment[:2], dtype=float)

    def _candidates(
        self, walk: Walk, plan: GaitPlan, t: float, local: float, k: int
    ) -> tuple[list[qp.Candidate], qp.Capacity]:
        """The footsteps the QP may move (no crossover region) and the CoP's capacity for
        ``plan`` at ``t``: the same for every QP solved on that plan in one tick (``crossover``
        solves it uncrossed and crossed in front and behind), so they are kept for it."""
        kept = self._kept_candidates
        if (
            kept is not None and kept[0] is walk and kept[1] is plan and kept[2] == t
            and kept[3] == local and kept[4] == k
        ):  # fmt: skip
            return kept[5], kept[6]
        weights = plan.preview.dcm_weights(local)  # a_j(t) = w(t)·s_j (eqs. 22, 33-35)
        swing = walk.swing
        candidates = []
        for j in range(k, min(k + MULTI_STEPS, len(plan.steps))):
            fixed = None
            if j == k and walk.swing_step == k and swing.frozen(t):
                fixed = swing.target[:2] - plan.steps[k].position[:2]
            selection = plan.selection(j)
            candidates.append(
                qp.Candidate(
                    plan.steps[j], 1.0 / plan.adjustment_gain(j),
                    plan.adjustment_instant(j) - t, fixed, self.tread_box(plan.steps[j]),
                    float(weights @ selection),
                )
            )  # fmt: skip
        capacity = self.capacity(walk, plan, t, local)
        self._kept_candidates = (walk, plan, t, local, k, candidates, capacity)
        return candidates, capacity

    def capacity(self, walk: Walk, plan: GaitPlan, t: float, local: float) -> qp.Capacity:
        """What the CoP can still remove of ε = ξ − ξ_adj (:mod:`.qp`): an offset δ from v_ref
        held for CAPACITY_TIME_CONSTANTS · b removes (1 − e^{−τ/b}) δ; v_ref + δ stays
        :func:`capacity_margin` inside the sole of the stance foot (in its axes).  In double support
        the box moves from the old stance foot's sole to the new one's (start: from both feet's
        bounding box; stop: to it) as the nominal VRP does (:meth:`_transfer_progress`), so the
        capacity, and with it the QP's answer, is continuous at every lift-off and touchdown
        (ξ_adj never jumps)."""
        placed = walk.placed
        contact = plan.contact(t)
        kind = contact.kind
        # the nominal VRP: with the observer both v_ref and the soles' image in VRP space move
        # by the same −b²F̂/m (eqs. 47-49), so the CoP's room is read without that shift
        v = plan.preview.vrp(local)[:2] if local < plan.duration else plan.preview.waypoints[-1][:2]
        if kind == "ss":
            boxes, s = [self.sole_box([placed[OTHER[contact.swing_side]]])], 0.0
        else:
            s = self._transfer_progress(plan, local, contact, v) if kind != "stand" else 1.0
            both = self.sole_box([placed[x] for x in SIDES])
            k = plan.next_modifiable_step(t)
            nxt = self.sole_box([plan.stance_for(k)]) if k is not None else both
            if kind == "ds" and contact.step >= 0:  # after footstep contact.step landed
                old = self.sole_box([plan.stance_for(contact.step)])
                boxes = [old, nxt]
            elif kind == "ds" or kind in ("start_a", "stand"):
                boxes = [both, both] if kind != "ds" else [both, nxt]
            elif kind == "start_b":
                boxes = [both, nxt]
            else:  # stop: from the last stance foot to both feet
                last = self.sole_box([plan.stance_for(len(plan.steps) - 1)])
                boxes = [last, both]
        lo = (1.0 - s) * boxes[0][0] + s * boxes[-1][0]
        hi = (1.0 - s) * boxes[0][1] + s * boxes[-1][1]
        g = 1.0 - math.exp(-CAPACITY_TIME_CONSTANTS)
        lo = np.minimum(g * (lo - v), 0.0)
        hi = np.maximum(g * (hi - v), 0.0)
        return qp.Capacity(qp.EYE2, lo, hi)

    def _transfer_progress(self, plan: GaitPlan, local: float, contact, v: np.ndarray) -> float:
        """How far (0 → 1) the nominal VRP ``v`` (at ``local``) has moved through the present
        double-support (or start/stop) phase: the projection of v − v(start) on
        v(end) − v(start), the VRP's own S-curve (Table I's orders 1/3/5), not the time's share
        of the phase.  The capacity's box follows the VRP with it: moved linearly in time, the
        box was a third of a phase behind (or ahead of) the VRP in mid-transfer, which sat on
        its edge, and the QP read "the CoP can do nothing on that side" from a support polygon
        that is the two feet's hull: 0.5 cm of CoP shortfall in every double support of a G1
        under a 15 % pull with a 1 cm DCM error, on which ``multi_step_timing`` re-timed its
        steps into a fall.  At both ends of the phase the progress is exactly 0 and 1, as the
        time's share was, so the capacity stays continuous at every lift-off and touchdown."""
        preview = plan.preview
        T = float(preview.durations[contact.phase])
        cached = self._transfer
        if cached is None or cached[0] is not preview or cached[1] != contact.phase:
            start = local - contact.t_phase
            v0 = preview.vrp(start)[:2]
            d = preview.vrp(min(start + T, plan.duration - 1e-12))[:2] - v0
            cached = self._transfer = (preview, contact.phase, v0, d, float(d @ d))
        _, _, v0, d, dd = cached
        if dd < 1e-8:  # the VRP hardly moves in this phase: the time's share
            return min(max(contact.t_phase / T, 0.0), 1.0) if T > 0.0 else 1.0
        return min(max(float((v - v0) @ d) / dd, 0.0), 1.0)

    def sole_box(self, feet: list[Footstep]) -> tuple[np.ndarray, np.ndarray]:
        """World-axes bounding box (lo, hi) of the soles, :func:`capacity_margin` inside.

        :func:`~dcmviz.robots.geometry.soles_box`, kept per placement of the feet (read-only
        arrays): the capacity and every timing candidate's capture check ask for the same few
        feet many times a tick (``crossover``: six boxes a tick)."""
        key = tuple((float(f.position[0]), float(f.position[1]), float(f.yaw)) for f in feet)
        box = self._boxes.get(key)
        if box is None:
            x_lo, y_lo, x_hi, y_hi = soles_box(
                key,
                self.spec.foot_length_m - 2 * capacity_margin(self.spec.foot_length_m),
                self.spec.foot_width_m - 2 * capacity_margin(self.spec.foot_width_m),
            )
            lo, hi = np.array([x_lo, y_lo]), np.array([x_hi, y_hi])
            lo.flags.writeable = hi.flags.writeable = False
            if len(self._boxes) >= SOLE_BOXES_KEPT:
                self._boxes.clear()
            box = self._boxes[key] = (lo, hi)
        return box

    def shape_vrp(
        self,
        v: np.ndarray,
        support: dict[str, bool],
        placed: dict[str, Footstep],
        shift: np.ndarray | None = None,
    ) -> np.ndarray:
        """The commanded VRP brought into the support polygon (the soles bearing weight, their
        hull in double support) by the projection that keeps its lateral part first (metric
        LATERAL_PRIORITY² on the feet's lateral axis) when it lies laterally beyond both feet:
        no footstep can take a lateral error towards the stance foot, a forward one the next
        footsteps can.  A VRP inside, or laterally between the feet, is kept (the backend's
        support then decides, as for the paper's strategy).

        With the observer the polygon is the soles' image in VRP space, moved by the reference
        ``shift`` (eqs. 47–49 and the moment shift: the contact CoP lies −shift from the VRP);
        on the soles themselves a 9 % tug of war kept Talos's CoP 7 cm inside its stance foot
        and it fell (multi_step, presets/tug_of_war.toml at 80 N)."""
        if shift is not None and (shift[0] or shift[1]):
            offset = np.array([shift[0], shift[1], 0.0])
            return self._lateral_first(v - offset, support, placed) + offset
        return self._lateral_first(v, support, placed)

    def _lateral_first(
        self, v: np.ndarray, support: dict[str, bool], placed: dict[str, Footstep]
    ) -> np.ndarray:
        """:meth:`shape_vrp` on the soles themselves."""
        feet = [placed[s] for s in SIDES if support.get(s)]
        if not feet:
            return v
        yaw = math.atan2(sum(math.sin(f.yaw) for f in feet), sum(math.cos(f.yaw) for f in feet))
        c, s_ = math.cos(yaw), math.sin(yaw)
        to_local = np.array([[c, s_], [-s_ * LATERAL_PRIORITY, c * LATERAL_PRIORITY]])
        local_v = to_local @ v[:2]
        lateral = [float(to_local[1] @ placed[x].position[:2]) for x in SIDES]
        beyond = max(min(lateral) - local_v[1], local_v[1] - max(lateral), 0.0)
        if beyond == 0.0:  # between the feet: a step can take it (most ticks: no polygon)
            return v
        corners = np.vstack(
            [sole_corners(f.position, f.yaw, self.spec.foot_length_m, self.spec.foot_width_m)
             for f in feet]
        )  # fmt: skip
        polygon = convex_hull(corners @ to_local.T)
        p, d = project_to_polygon(local_v, polygon)
        if d == 0.0:
            return v
        # blended in over PRIORITY_BLEND_M beyond the outer foot: continuous in v
        alpha = min(beyond / (LATERAL_PRIORITY * PRIORITY_BLEND_M), 1.0)  # beyond: scaled
        moved = np.linalg.solve(to_local, np.asarray(p, float)) - v[:2]
        return np.array([*(v[:2] + alpha * moved), v[2]])
