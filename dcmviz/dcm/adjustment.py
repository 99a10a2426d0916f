"""Analytical step adjustment and smooth DCM reference adaptation (Sec. III-A/B, eqs. 27–35).

All mappings are (scalar)·I₃ blocks, so the 3-D matrices of the paper reduce to scalar weights:
``selection`` is S_adj of eq. (29) as an (n_wp,) weight vector (1 for every VRP waypoint of the
next modifiable footstep, 0 elsewhere; 0.5 where a waypoint is the mid-point of two feet), and

* eq. (30): Δξ_adj,0,φ_fa = (W_xi_ref_0[φ_fa] · s) Δv_adj,
* eq. (32): A_adj = (3row(A_xi_ref_0, φ_fa) S_adj)⁻¹ = I / (W_xi_ref_0[φ_fa] · s),
* eq. (35): d_φ(t) = (w(t) · s) / (W_xi_ref_0[φ_fa] · s), with ξ_ref(t) = w(t) @ v_wp (eq. 22).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dcmviz.dcm.preview import Preview


def adjustment_gain(preview: Preview, phi_fa: int, selection: NDArray) -> float:
    """Scalar a with A_adj = a I (eq. 32): the inverse of 3row(A_xi_ref_0, φ_fa) S_adj."""
    w0 = float(preview.W_xi_ref_0[phi_fa] @ selection)
    if w0 == 0.0:
        raise ValueError(f"selection does not affect the DCM start point of phase {phi_fa}")
    return 1.0 / w0


def step_adjustment(
    preview: Preview, phi_fa: int, selection: NDArray, xi_error: NDArray, *, horizontal: bool = True
) -> NDArray:
    """Δv_adj = A_adj ξ̃ (eq. 32), assuming the DCM error persists until phase φ_fa (eq. 31).

    With ``horizontal`` only the x, y components are kept (flat ground, as in the paper's Sec. IV).
    """
    dv = adjustment_gain(preview, phi_fa, selection) * np.asarray(xi_error, dtype=float)
    if horizontal:
        dv = np.array([dv[0], dv[1], 0.0])
    return dv


def adaptation_factor(preview: Preview, t: float, phi_fa: int, selection: NDArray) -> float:
    """d_φ(t) of eq. (35): ≪ 1 long before phase φ_fa, exactly 1 at its start (t in preview time)."""
    return float(preview.dcm_weights(t) @ selection) * adjustment_gain(preview, phi_fa, selection)


def dcm_adjustment(
    preview: Preview,
    t: float,
    selection: NDArray,
    dv_adj: NDArray,
    weights: NDArray | None = None,
) -> NDArray:
    """Δξ_adj,φ(t) = A_xi_ref_φ(t) S_adj Δv_adj (eq. 34), valid for any (e.g. clipped) Δv_adj;
    ``weights``: ``preview.dcm_weights(t)`` if the caller has it already (several footsteps)."""
    w = preview.dcm_weights(t) if weights is None else weights
    return float(w @ selection) * np.asarray(dv_adj, dtype=float)


def adjusted_waypoints(waypoints: NDArray, selection: NDArray, dv_adj: NDArray) -> NDArray:
    """v_wp,adj = v_wp + S_adj Δv_adj (eqs. 27, 29)."""
    return np.asarray(waypoints, dtype=float) + np.outer(selection, dv_adj)
