"""The paper's step adjustment (§III-A, eqs. 27–35): the next footstep takes the DCM error."""

from __future__ import annotations

import numpy as np

from dcmviz.dcm import dcm_adjustment
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
        target = self.target(plan, k, xi_error, plan.stance_for(k), max_adjustment)
        retarget = False
        if walk.swing_step == k:
            if walk.swing.frozen(t):
                target = np.array([*walk.swing.target[:2], plan.steps[k].position[2]])
            else:
                retarget = True
        dv = target - plan.steps[k].position
        weights = preview.dcm_weights(local)  # w(t) of eq. (34), for both footsteps
        delta = dcm_adjustment(preview, local, plan.selection(k), dv, weights)
        residual = xi_error - dv / plan.adjustment_gain(k)
        residual[2] = 0.0
        following = None
        k2 = k + 1
        if k2 < len(plan.steps) and float(residual @ residual) > 1e-18:
            stance = plan.steps[k].moved(target)  # footstep k where it will land
            target2 = self.target(plan, k2, residual, stance, max_adjustment)
            dv2 = target2 - plan.steps[k2].position
            delta = delta + dcm_adjustment(preview, local, plan.selection(k2), dv2, weights)
            following = (k2, target2)
        return Adjustment(delta, (k, target), following, retarget)
