"""Step timing (dcmviz.gait.timing): re-timed plans against the closed form and numerical
integration, the candidate timings' limits, the reachable DCM against extreme CoPs, and a swing
re-timed mid-flight."""

from __future__ import annotations

import numpy as np

from dcmviz.config import Config
from dcmviz.gait import Footstep, SwingTrajectory, plan_from_config, timing


def test_retimed_order_0_phase_follows_the_closed_form() -> None:
    """ξ(T) = v + e^{T/b}(ξ_0 − v) over a re-timed single support (order 0: constant VRP)."""
    config = Config().replace(dcm={"order": 0})
    plan = plan_from_config(config)
    phase = 8  # a single support
    assert plan.phase_kind[phase] == "ss"
    durations = plan.preview.durations.copy()
    durations[phase] = 0.45
    durations[phase + 1] = 0.5
    p = timing.retimed(plan, durations)
    t0 = float(p.preview.phase_start_times[phase])
    v = p.preview.vrp(t0 + 0.1)
    got = p.preview.dcm(t0 + 0.45 - 1e-9)
    want = timing.dcm_after(p.preview.dcm(t0), v, 0.45, config.dcm.b)
    np.testing.assert_allclose(got, want, atol=1e-7)
    assert p.steps == plan.steps and np.array_equal(p.waypoints, plan.waypoints)


def test_candidates_respect_the_limits() -> None:
    plan = plan_from_config(Config())
    phase = 8
    t_phase = 0.5
    local = float(plan.preview.phase_start_times[phase]) + t_phase
    cands = timing.timing_candidates(plan, local)
    assert np.array_equal(cands[0], plan.preview.durations)  # nominal first
    for d in cands:
        assert d[phase] >= t_phase + timing.MIN_REMAINING_S - 1e-9 or d[phase] == 0.7
        assert d[phase + 1] >= timing.MIN_DS_S and d[phase + 2] >= timing.MIN_SS_S
        np.testing.assert_array_equal(d[:phase], plan.preview.durations[:phase])
        np.testing.assert_array_equal(d[phase + 3 :], plan.preview.durations[phase + 3 :])


def test_a_shortened_swing_does_not_jump() -> None:
    """Re-timing mid-swing keeps position and velocity (horizontal C², height C⁰ with its rate
    scaled) and lands on the target at the new touchdown."""
    lift = Footstep("right", np.array([0.0, -0.085, 0.0]), 0.0)
    touch = Footstep("right", np.array([0.4, -0.085, 0.0]), 0.0)
    swing = SwingTrajectory.between(1.0, 1.7, lift, touch)
    t, dt = 1.3, 1e-4
    short = swing.retime(t, 1.5)
    p0, v0, a0, *_ = swing.sample(t)
    p1, v1, a1, *_ = short.sample(t)
    np.testing.assert_allclose(p1, p0, atol=1e-9)
    np.testing.assert_allclose(v1[:2], v0[:2], atol=1e-9)
    np.testing.assert_allclose(a1[:2], a0[:2], atol=1e-6)
    assert abs(v1[2] - v0[2] * 0.7 / ((1.5 - t) / (1.7 - t) * 0.7)) < 1.0  # scaled, bounded
    pt, vt, *_ = short.sample(1.5)
    np.testing.assert_allclose(pt, touch.position, atol=1e-9)
    np.testing.assert_allclose(vt, 0.0, atol=1e-9)
    path = np.array([short.sample(s)[0] for s in np.arange(t, 1.5, dt)])
    assert np.max(np.linalg.norm(np.diff(path, axis=0), axis=1)) < 3.0 * dt  # < 3 m/s


def _integrate_dcm(xi0: np.ndarray, vrp, duration: float, n: int = 4000) -> np.ndarray:
    """RK4 of ξ̇ = (ξ − v(t))/b with b = 0.3 (eq. 2), independent of the closed forms."""
    b, h = 0.3, duration / n
    xi = np.asarray(xi0, float).copy()
    for i in range(n):
        t = i * h
        f = lambda s, x: (x - vrp(s)) / b  # noqa: E731
        k1 = f(t, xi)
        k2 = f(t + h / 2, xi + h / 2 * k1)
        k3 = f(t + h / 2, xi + h / 2 * k2)
        k4 = f(t + h, xi + h * k3)
        xi = xi + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return xi


def test_reachable_dcm_is_what_the_extreme_cops_reach() -> None:
    """The interval ends of timing.reachable_dcm are the DCMs that the CoP held at the supports'
    opposite edges reaches (numerical integration), and no CoP inside the supports, however it
    switches, leaves the interval (random piecewise-constant CoPs)."""
    b = 0.3
    xi0 = np.array([0.10, 0.14])
    segs = [
        (0.15, np.array([0.5, 0.02]), np.array([0.7, 0.15])),  # the rest of a single support
        (0.1, np.array([0.5, -0.12]), np.array([0.9, 0.15])),  # double support
        (0.35, np.array([0.69, -0.12]), np.array([0.9, 0.01])),  # the other foot's support
    ]
    lo, hi = timing.reachable_dcm(xi0, segs, b)

    def through(pieces) -> np.ndarray:  # integrated piece by piece (the CoP jumps between)
        xi = xi0
        for duration, cop in pieces:
            xi = _integrate_dcm(xi, lambda _t, cop=cop: cop, duration, n=400)
        return xi

    np.testing.assert_allclose(lo, through([(d, top) for d, _, top in segs]), atol=1e-9)
    np.testing.assert_allclose(hi, through([(d, low) for d, low, _ in segs]), atol=1e-9)
    rng = np.random.default_rng(3)
    for _ in range(5):  # any CoPs inside the supports, switching 3 times per phase
        pieces = []
        for d, low, top in segs:
            cuts = np.diff(np.concatenate([[0.0], np.sort(rng.uniform(0, d, 2)), [d]]))
            pieces += [(c, low + rng.uniform(0, 1, 2) * (top - low)) for c in cuts]
        got = through(pieces)
        assert np.all(got >= lo - 1e-9) and np.all(got <= hi + 1e-9)
    region = (np.array([0.8, 0.3]), np.array([1.0, 0.45]))
    short = timing.capture_shortfall(xi0, segs, region, b)
    np.testing.assert_allclose(short, np.maximum(np.maximum(lo - region[1], region[0] - hi), 0))


def test_retimed_plan_dcm_is_the_integrated_dcm_of_its_vrp() -> None:
    """A plan re-timed in three phases at once (order 5): its closed-form ξ_ref at each new
    touchdown equals ξ integrated numerically through the re-timed VRP (eqs. 2, 10, 22)."""
    config = Config()
    plan = plan_from_config(config)
    phase = 8
    durations = plan.preview.durations.copy()
    durations[phase : phase + 3] = [0.45, 0.05, 0.42]
    p = timing.retimed(plan, durations)
    start = float(p.preview.phase_start_times[phase])
    end = float(p.preview.phase_start_times[phase + 3])
    got = _integrate_dcm(p.preview.dcm(start), lambda s: p.preview.vrp(start + s), end - start)
    np.testing.assert_allclose(got, p.preview.dcm(end), atol=1e-7)
    assert np.linalg.norm(p.preview.dcm(end) - plan.preview.dcm(end)) > 1e-3  # it did change


def test_a_swing_the_timing_ends_lands_where_the_foot_is() -> None:
    """The point mass with the G1's numbers, multi_step_timing, the paper's push pair at 2× from
    the double support before a left stance (bench/robustness.py): the strategy shortens the
    right foot's swing while it goes, and the swing ends inside a re-timing, not at the walk's
    clock.  Each footstep is committed where the foot was commanded on the tick before it landed
    (the point mass's feet follow their commands exactly); the walker used to read the new
    double support off the re-timed plan alone, command the foot for a tick to where it had
    lifted off, and commit the footstep there (0.3 m behind the swing)."""
    from helpers import robustness_bench

    from dcmviz.session import Session

    rb = robustness_bench()

    base = rb.walking_config("g1", sim="lip", overrides=['control.recovery="multi_step_timing"'])
    mass = Session(base, backend="lip").mass
    session = Session(rb.push_config(base, mass, 2.0, 3.625), backend="lip")
    last: dict[str, np.ndarray] = {}
    checked = shortened = 0
    while session.t < 4.4 and not session.fell:
        records = len(session.walker.walk.records)
        command = session.step()
        walk = session.walker.walk
        if len(walk.records) > records:
            record = walk.records[-1]
            assert np.allclose(record.position[:2], last[record.side][:2], atol=1e-12)
            checked += 1
            t_lift, t_touch = walk.plan.swing_window(record.step)
            shortened += t_touch - t_lift < base.gait.t_ss - 0.05
        if command.swing_side is not None:
            last[command.swing_side] = np.array(command.feet[command.swing_side].position)
    assert checked >= 3 and shortened >= 1


def test_a_persisting_push_is_a_cop_box_moved_by_the_observers_shift() -> None:
    """The re-timing's capture check with a push assumed to go on for τ moves the CoP boxes of
    the first τ s by s = −b² F/m (``step_timing._persist``): its reachable DCMs equal those of
    ξ̇ = (ξ − p)/b + b F/m integrated (RK4) with the CoP p held at each box's corners and F on
    for the first τ s."""
    from dcmviz.recovery.step_timing import _persist

    b, m = 0.25, 33.0
    force = np.array([48.0, -20.0])
    shift = -(b**2) * force / m
    segments = [
        (0.25, np.array([-0.05, -0.15]), np.array([0.15, 0.12])),  # double support
        (0.5, np.array([0.0, 0.05]), np.array([0.2, 0.12])),  # single support
        (0.2, np.array([0.2, -0.1]), np.array([0.4, 0.12])),
    ]
    xi0, tau = np.array([0.08, 0.1]), 0.4
    lo, hi = timing.reachable_dcm(xi0, _persist(segments, tau, shift), b)

    def integrate(pick) -> np.ndarray:
        xi, t, dt = xi0.copy(), 0.0, 1e-4
        for length, box_lo, box_hi in segments:
            p = np.where(pick, box_hi, box_lo)
            for _ in range(round(length / dt)):

                def rate(x, s, p=p):
                    return (x - p) / b + (b * force / m if s < tau else 0.0)

                k1 = rate(xi, t)
                k2 = rate(xi + 0.5 * dt * k1, t + 0.5 * dt)
                k3 = rate(xi + 0.5 * dt * k2, t + 0.5 * dt)
                k4 = rate(xi + dt * k3, t + dt)
                xi, t = xi + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4), t + dt
        return xi

    # the lowest ξ comes from the CoP held at the boxes' upper corners, and the reverse
    np.testing.assert_allclose(lo, integrate(np.array([True, True])), atol=2e-4)
    np.testing.assert_allclose(hi, integrate(np.array([False, False])), atol=2e-4)
    plain_lo, plain_hi = timing.reachable_dcm(xi0, segments, b)
    assert np.all(np.abs(lo - plain_lo) > 0.01)  # the force's 0.4 s move it by centimetres
