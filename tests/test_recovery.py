"""Multi-step adjustment (dcmviz.recovery): the QP against a dense solve of eq. (28)."""

from __future__ import annotations

import numpy as np
import pytest

from dcmviz import recovery
from dcmviz.config import Config
from dcmviz.gait import plan_from_config
from dcmviz.recovery import Candidate
from dcmviz.robots import get_spec
from dcmviz.session import Session


def candidates_from_dense(plan, k: int, t: float, n: int = 3) -> list[Candidate]:
    """Leverages c_j from the dense A_xi_ref_0 (eq. 20) and S_adj (eq. 29), row φ_fa,j (eq. 28)."""
    A = plan.preview.A_xi_ref_0  # (3 n_phi, 3 n_wp)
    out = []
    for j in range(k, k + n):
        S = np.kron(plan.selection(j)[:, None], np.eye(3))  # (3 n_wp, 3)
        if plan.is_closing_step(j):
            rows = plan.preview.A_xi_ref_T[-3:]  # the plan's end: ξ_ref_T of the last phase
            instant = plan.t_end
        else:
            phi = plan.first_affected_phase(j)
            rows = A[3 * phi : 3 * phi + 3]
            instant = plan.phase_start(phi)
        block = rows @ S  # = c_j I₃
        np.testing.assert_allclose(block, block[0, 0] * np.eye(3), atol=1e-12)
        out.append(Candidate(plan.steps[j], float(block[0, 0]), instant - t))
    return out


@pytest.mark.parametrize("order", [1, 3, 5])
def test_qp_equals_dense_weighted_least_squares_when_constraints_are_inactive(order) -> None:
    config = Config().replace(dcm={"order": order})
    plan = plan_from_config(config)
    k, t, b = 3, plan.phase_start(6) + 0.1, config.dcm.b
    cands = candidates_from_dense(plan, k, t)
    error = np.array([0.004, -0.006, 0.0])  # small: no reach limit is touched
    got = recovery.solve(cands, plan.stance_for(k), error, get_spec("talos"), 0.3, b)
    # dense: minimise Σ ω_j |Δv_j|² + ρ |ξ̃ − C Δv|² as one stacked least-squares problem
    lead = np.array([c.lead_time_s for c in cands])
    omega = np.exp(np.maximum(lead - lead[0], 0.0) / b)
    C = np.hstack([c.leverage * np.eye(2) for c in cands])
    rho = recovery.CONDITION_WEIGHT
    M = np.vstack([np.sqrt(rho) * C, np.diag(np.repeat(np.sqrt(omega), 2))])
    rhs = np.concatenate([np.sqrt(rho) * error[:2], np.zeros(2 * len(cands))])
    dense = np.linalg.lstsq(M, rhs, rcond=None)[0].reshape(-1, 2)
    np.testing.assert_allclose(np.array(got)[:, :2], dense, atol=1e-9)
    closed = recovery.least_squares(cands, error, b)
    np.testing.assert_allclose(np.array(got), np.array(closed), atol=1e-9)
    # eq. (31) holds: the adjusted references cancel the error at the instants
    assert np.linalg.norm(C @ dense.ravel() - error[:2]) < 1e-3 * np.linalg.norm(error)


def test_reach_limits_hold_and_the_next_footstep_takes_the_rest() -> None:
    config = Config()
    plan = plan_from_config(config)
    spec = get_spec("talos")
    k = 3  # a footstep of the right foot (first swing is the left one)
    t = plan.phase_start(2 * k + 2) + 0.1
    cands = candidates_from_dense(plan, k, t)
    side = plan.steps[k].side
    towards_stance = np.array([0.0, 0.3 if side == "right" else -0.3, 0.0])
    dvs = recovery.solve(cands, plan.stance_for(k), towards_stance, spec, 0.4, config.dcm.b)
    stance = plan.stance_for(k)
    landed = plan.steps[k].position + dvs[0]
    lateral = (
        -(landed[1] - stance.position[1]) if side == "right" else landed[1] - stance.position[1]
    )
    assert lateral >= spec.min_step_width_m - 1e-9  # no leg crossing
    assert np.linalg.norm(dvs[1][:2]) > 0.05  # the footstep after it steps out instead


def test_multi_step_walk_is_nominal_undisturbed_and_recovers_pushes() -> None:
    config = Config().replace(sim={"backend": "lip"}, control={"recovery": "multi_step"})
    s = Session(config, backend="lip")
    s.run(s.plan.duration + 1.0)
    assert not s.fell and s.metrics.max_dcm_error_m < 1e-3
    s = Session(config, backend="lip")
    s.push((0.0, -150.0, 0.0), 0.2, start=3.95)
    s.run(12.0)
    assert not s.fell


@pytest.mark.parametrize("strategy", ["next_step", "multi_step"])
def test_tick_shows_the_footstep_after_the_adjusted_one_when_it_takes_the_rest(strategy) -> None:
    """A push towards the stance foot: the swinging foot may not cross, so the footstep after it
    steps out; the tick carries both for the dashboard's ghosts."""
    config = Config().replace(sim={"backend": "lip"}, control={"recovery": strategy})
    s = Session(config, backend="lip")
    seen = []
    s.subscribe(lambda tick: seen.append(tick.recovery_step) if tick.recovery_step else None)
    s.push((0.0, 150.0, 0.0), 0.2, start=3.95)  # left, towards the left stance foot
    s.run(5.0)
    assert seen, "the footstep after the adjusted one never moved"
    assert max(step.position[1] for step in seen) > 0.085 + 0.05  # the left foot steps out
