"""Headless MuJoCo rollouts of the humanoids under the whole-body QP."""

from __future__ import annotations

import numpy as np
import pytest

from dcmviz import GRAVITY
from dcmviz.sim.mujoco_sim import MujocoBackend
from dcmviz.state import FootTarget, MeasuredState, WalkerCommand

E_Z = np.array([0.0, 0.0, 1.0])


def balance_command(
    backend: MujocoBackend, state: MeasuredState, xi_d: np.ndarray, feet: dict, k_xi: float = 3.0
) -> WalkerCommand:
    """Scripted DCM balance: v = ξ + k b (ξ - ξ_d), contact force m/b² (x - v) + m g e_z (eq. 4)."""
    m, b = backend.mass, backend.spec.b_nominal_s
    xi = state.dcm(b)
    v = xi + k_xi * b * (xi - xi_d)
    com_force = m / b**2 * (state.com - v)
    return WalkerCommand(
        t=state.t,
        support={"left": True, "right": True},
        feet={s: FootTarget(position=p) for s, p in feet.items()},
        swing_side=None,
        com_force=com_force,
        contact_force=com_force + m * GRAVITY * E_Z,
        xi=xi,
        xi_ref=xi_d,
        xi_adj=xi_d,
        v_ref=xi_d,
        v_cmd=v,
        f_hat=np.zeros(3),
    )


@pytest.mark.slow
@pytest.mark.parametrize("robot", ["talos", "g1"])
def test_stands_three_seconds(robot):
    backend = MujocoBackend(robot)
    state = backend.reset()
    xi_d = state.com.copy()
    feet = {s: p.copy() for s, p in state.feet.items()}
    for _ in range(int(3.0 / backend.control_dt)):
        state = backend.step(balance_command(backend, state, xi_d, feet))
        assert not backend.fell()
    assert np.linalg.norm(state.dcm(backend.spec.b_nominal_s) - xi_d) < 0.01
    for s in feet:
        assert np.linalg.norm(state.feet[s] - feet[s]) < 0.005
        assert state.in_contact[s]
