"""The paper's step adjustment (§III-A, eqs. 27–35): the next footstep takes the DCM error."""

from __future__ import annotations

import numpy as np

from dcmviz.gait.walk import Walk
from dcmviz.recovery.base import NO_ADJUSTMENT, Adjustment, RecoveryStrategy


class NextStep(RecoveryStrategy):
    """``next_step``: Δv_adj = A_adj ξ̃ on the next modifiable footstep (eq. 32), horizontal,
    limited to the reach, and the adapted reference ξ_adj = ξ_ref + Δξ_adj (eqs. 33–35).

    While its swing is frozen (the last 20 % of single support) footstep k keeps the target the
    foot is already going to.  What footstep k cannot take, the part of ξ̃ its Δv_k does not
    cancel at its own adjustment instant (eq. 31), r = ξ̃ − Δv_k / A_adj,k, goes to the footstep
    after it, by the same eq. (32).  Every term is continuous in time, and at k's touchdown the
    committed footstep makes the new ξ_ref carry exactly the Δξ of footstep k (the next one's
    term is unchanged): ξ_adj and the commanded VRP do not jump when a push saturates or
    outlasts an adjustment.
    """

    name = "next_step"

    def adjust(
        self, walk: Walk, t: float, local: float, xi_error: np.ndarray, max_adjustment: float
    ) -> Adjustment:
        plan = walk.plan
        preview = plan.preview
        k = plan.next_modifiable_step(t)
        if k is None:
            return NO_ADJUSTMENT
        nominal = plan.steps[k]
        retarget = False
        if walk.swing_step == k and walk.swing.frozen(t):  # the target the foot is going to
            target = np.array([*walk.swing.target[:2], nominal.position[2]])
        else:
            target = self.target(plan, k, xi_error, plan.stance_for(k), max_adjustment)
            retarget = walk.swing_step == k
        # per component in floats (3-vectors: numpy's per-call overhead would be most of the
        # cost), the same operations as on arrays
        tx, ty, tz = target.tolist()
        nx, ny, nz = nominal.position.tolist()
        dx, dy, dz = tx - nx, ty - ny, tz - nz
        weights = preview.dcm_weights(local)  # w(t) of eq. (34), for both footsteps
        d = float(weights @ plan.selection(k))  # Δξ_adj = (w(t) · s) Δv_adj, eq. (34)
        delta = (d * dx, d * dy, d * dz)
        a_adj = plan.adjustment_gain(k)
        ex, ey = float(xi_error[0]), float(xi_error[1])
        rx, ry = ex - dx / a_adj, ey - dy / a_adj  # the residual, horizontal
        following = None
        k2 = k + 1
        if k2 < len(plan.steps) and rx * rx + ry * ry > 1e-18:
            stance = nominal.moved(target)  # footstep k where it will land
            target2 = self.target(plan, k2, (rx, ry), stance, max_adjustment)
            x2, y2, z2 = (target2 - plan.steps[k2].position).tolist()
            d2 = float(weights @ plan.selection(k2))  # eq. (34) for footstep k2
            delta = (delta[0] + d2 * x2, delta[1] + d2 * y2, delta[2] + d2 * z2)
            following = (k2, target2)
        return Adjustment(np.array(delta), (k, target), following, retarget)
