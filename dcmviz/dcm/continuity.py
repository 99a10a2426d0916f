"""Continuous standing-to-walking-to-standing transitions (Sec. II-D, D1–D3, eqs. 25, 26).

B_wp of eq. (25) is the identity except for its second block row, 3row(A_xi_ref_0, 1), so
eq. (26) is solved in O(n) for the one waypoint it determines, v_wp,2 (index 1 here).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dcmviz.dcm.interpolation import check_points
from dcmviz.dcm.preview import PhaseSchedule


def _schedule_with_three_waypoints(durations: ArrayLike, b: float, order: int) -> PhaseSchedule:
    schedule = PhaseSchedule(durations, b, order)
    if schedule.n_waypoints < 3:
        raise ValueError(
            f"durations has {schedule.n_phases} entry: standing-to-walking continuity (D1–D3) "
            "needs at least 2 transition phases (n_wp = len(durations) + 1 ≥ 3)"
        )
    return schedule


def continuity_matrix(durations: ArrayLike, b: float, order: int) -> NDArray[np.float64]:
    """Dense VRP waypoint boundary condition matrix B_wp (3 n_wp, 3 n_wp) of eq. (25).

    Block rows: D1 (I on v_wp,1), D2 (3row(A_xi_ref_0, 1)), the unconstrained waypoints
    v_wp,uc, D3 (I on v_wp,n_wp). For inspection and tests; ``continuity_waypoints`` does
    not build it.
    """
    schedule = _schedule_with_three_waypoints(durations, b, order)
    B = np.eye(schedule.n_waypoints)
    B[1] = schedule.first_xi_ref_0_row()
    return np.kron(B, np.eye(3))


def continuity_waypoints(
    v_stand_ini: ArrayLike,
    v_uc: ArrayLike,
    v_stand_end: ArrayLike,
    durations: ArrayLike,
    b: float,
    order: int,
) -> NDArray[np.float64]:
    """VRP waypoints v_wp (n_wp, 3) satisfying D1–D3, eq. (26): v_wp = B_wp⁻¹ b_wp.

    ``v_stand_ini`` (3,) and ``v_stand_end`` (3,) are the standing VRP references (m),
    ``v_uc`` (n_wp − 3, 3) the freely assigned waypoints v_wp,3 … v_wp,n_wp−1, ``durations``
    (n_wp − 1,) the phase durations (s). D1: v_wp,1 = v_stand_ini; D3: v_wp,n_wp = v_stand_end;
    D2: ξ_ref_0,1 = v_stand_ini, solved for v_wp,2 from the first row of eq. (20) in O(n).
    """
    schedule = _schedule_with_three_waypoints(durations, b, order)
    n_wp = schedule.n_waypoints
    v_stand_ini = check_points(v_stand_ini, "v_stand_ini", (3,))
    v_stand_end = check_points(v_stand_end, "v_stand_end", (3,))
    v_uc = check_points(v_uc, "v_uc", (n_wp - 3, 3))

    v_wp = np.empty((n_wp, 3))
    v_wp[0] = v_stand_ini  # D1
    v_wp[1] = 0.0
    v_wp[2:-1] = v_uc
    v_wp[-1] = v_stand_end  # D3
    # D2: ξ_ref_0,1 = w @ v_wp = v_stand_ini, linear in v_wp,2 with coefficient w[1].
    w = schedule.first_xi_ref_0_row()
    v_wp[1] = (v_stand_ini - w @ v_wp) / w[1]
    return v_wp
