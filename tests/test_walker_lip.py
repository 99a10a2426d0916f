"""The §III walker on the point-mass backend: nominal walking, the paper's push scenarios."""

import numpy as np
from scipy.integrate import solve_ivp

from dcmviz.config import apply_overrides, config_from_dict, load_preset
from dcmviz.session import Session

PRESETS = "presets"


def test_undisturbed_walk_is_exactly_nominal():
    config = load_preset(f"{PRESETS}/walk_forward.toml")
    s = Session(config, backend="lip")
    plan = s.plan
    x0 = s.last_state.com.copy()
    times, coms = [s.t], [x0]
    while s.t < plan.duration + 0.5:
        s.step()
        times.append(s.t)
        coms.append(s.last_state.com)
    assert not s.fell and s.steps_completed == config.gait.n_steps
    assert s.metrics.max_dcm_error_m < 1e-4
    for rec in s.realised_steps():
        assert np.linalg.norm(rec.adjustment) < 1e-4
    # independent: the CoM follows the DCM reference through eq. (2), ẋ = −(x − ξ_ref)/b
    b = config.dcm.b
    sol = solve_ivp(
        lambda t, x: -(x - plan.preview.dcm(t)) / b,
        (0.0, times[-1]),
        x0,
        t_eval=np.array(times),
        rtol=1e-10,
        atol=1e-12,
        max_step=0.01,
    )
    assert np.max(np.abs(sol.y.T - np.array(coms))) < 2e-4


def test_lateral_push_scenario_is_recovered_within_three_steps():
    """The paper's Sec. IV: ±25 N (scaled to ±30 N for Talos) for 1 s each, while walking."""
    config = load_preset(f"{PRESETS}/lateral_push.toml")
    s = Session(config, backend="lip")
    s.run(config.sim.duration)
    assert not s.fell
    h = s.history()
    step_time = config.gait.t_ss + config.gait.t_ds
    adjustments = np.array([[a["dx"], a["dy"]] for a in s.step_adjustments])
    assert np.max(np.abs(adjustments[:, 1])) > 0.02  # it really stepped to recover
    for push in config.pushes:
        end = push.start + push.duration
        during = (h["t"] >= push.start) & (h["t"] <= end + 0.5)
        assert h["dcm_error"][during].max() > 0.02  # the push really disturbed the DCM
        # three steps after the push (and before the next one starts)
        window = (h["t"] >= end + 3 * step_time) & (h["t"] < end + 3 * step_time + 0.25)
        assert window.any() and h["dcm_error"][window].max() < 0.01


def test_tug_of_war_needs_the_observer():
    config = load_preset(f"{PRESETS}/tug_of_war.toml")
    with_observer = Session(config, backend="lip")
    with_observer.run(config.sim.duration)
    assert not with_observer.fell
    assert with_observer.steps_completed == config.gait.n_steps
    # while the pull is held (133 N) the estimate has converged to it
    h = with_observer.history()
    held = (h["t"] > 10.0) & (h["t"] < 12.4)
    np.testing.assert_allclose(h["f_hat"][held, 1], 133.0, rtol=0.02)
    without = Session(apply_overrides(config, ["control.observer=false"]), backend="lip")
    without.run(config.sim.duration)
    assert without.fell


def test_step_adjustment_survives_a_push_tracking_alone_cannot():
    base = load_preset(f"{PRESETS}/walk_forward.toml")
    plan = Session(base, backend="lip").plan
    t_push = plan.swing_window(3)[0] + 0.35 - 0.1  # centred in the 4th single support
    # 40 N·s towards the swinging (right) foot; tracking alone survives about 20 N·s
    push = {"start": t_push, "duration": 0.2, "force": [0.0, -200.0, 0.0]}
    outcomes = {}
    for adjust in (False, True):
        config = config_from_dict(
            {
                **base.to_dict(),
                "pushes": [push],
                "control": {"step_adjustment": adjust, "observer": False},
            }
        )
        s = Session(config, backend="lip")
        s.run(config.sim.duration)
        outcomes[adjust] = s.fell
    assert outcomes == {False: True, True: False}


def test_continuous_mode_walks_a_minute():
    config = apply_overrides(
        load_preset(f"{PRESETS}/walk_forward.toml"), ['gait.mode="continuous"', "gait.turn=0.05"]
    )
    s = Session(config, backend="lip")
    s.run(60.0)
    assert not s.fell
    assert s.steps_completed >= int(60.0 / 0.9) - 2
    assert s.metrics.max_dcm_error_m < 1e-3  # replanning every step does not jolt the reference
