"""Preview (eqs. 5, 10, 13–23) against numerical integration, finite differences and a dense
implementation of eqs. (13)–(21) written out here."""

import numpy as np
import pytest
from dcm_reference import dense_matrices, phase_coefficients, table_i_polynomial
from scipy.integrate import solve_ivp

from dcmviz.dcm import Preview

ORDERS = (0, 1, 3, 5)
I3 = np.eye(3)


# --- independent reference implementation -------------------------------------------------------


def vrp_by_table_i(waypoints, durations, order, t_global):
    """Eq. (5) with (11), (12), evaluated sample by sample."""
    S = np.concatenate(([0.0], np.cumsum(durations)))
    out = []
    for t in t_global:
        phi = min(np.searchsorted(S, t, side="right") - 1, len(durations) - 1)
        P = table_i_polynomial(durations[phi], order)
        f = P(t - S[phi])
        out.append((1 - f) * waypoints[phi] + f * waypoints[phi + 1])
    return np.array(out)


def random_plan(rng: np.random.Generator, n_phases: int):
    waypoints = rng.uniform(-1.0, 1.0, (n_phases + 1, 3))
    durations = rng.uniform(0.1, 1.0, n_phases)
    b = rng.uniform(0.2, 0.5)
    return waypoints, durations, b


def inside_samples(p: Preview, per_phase: int = 5, margin: float = 0.05) -> np.ndarray:
    """Times strictly inside phases (away from the kinks at the boundaries)."""
    s = np.linspace(margin, 1 - margin, per_phase)
    return (p.phase_start_times[:, None] + p.durations[:, None] * s).ravel()


# --- eq. (6): the DCM solves the DCM dynamics ------------------------------------------------------


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_dcm_matches_backward_integration_of_eq_6(order: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    waypoints, durations, b = random_plan(rng, int(rng.integers(1, 9)))
    p = Preview(waypoints, durations, b, order)
    S = np.concatenate(([0.0], np.cumsum(durations)))
    xi = waypoints[-1].copy()  # terminal constraint (17)
    for phi in range(len(durations) - 1, -1, -1):
        T = durations[phi]
        P = table_i_polynomial(T, order)
        v0, vT = waypoints[phi], waypoints[phi + 1]

        def rhs(t, x, P=P, v0=v0, vT=vT):
            return (x - ((1 - P(t)) * v0 + P(t) * vT)) / b

        t_local = np.linspace(T, 0.0, 12)
        solution = solve_ivp(
            rhs, (T, 0.0), xi, t_eval=t_local, rtol=1e-10, atol=1e-12, method="DOP853"
        )
        assert solution.success
        np.testing.assert_allclose(p.dcm(S[phi] + t_local[:-1]), solution.y.T[:-1], atol=1e-6)
        xi = solution.y[:, -1]
        np.testing.assert_allclose(p.xi_ref_0[phi], xi, atol=1e-6)
    np.testing.assert_allclose(p.dcm(0.0), xi, atol=1e-6)


@pytest.mark.parametrize("order", ORDERS)
def test_dcm_satisfies_eq_6_by_finite_differences(order: int) -> None:
    waypoints, durations, b = random_plan(np.random.default_rng(10 + order), 7)
    p = Preview(waypoints, durations, b, order)
    t, h = inside_samples(p), 1e-6
    derivative = (p.dcm(t + h) - p.dcm(t - h)) / (2 * h)
    np.testing.assert_allclose(derivative, (p.dcm(t) - p.vrp(t)) / b, atol=1e-6)
    np.testing.assert_allclose(p.vrp(t), vrp_by_table_i(waypoints, durations, order, t), atol=1e-12)


@pytest.mark.parametrize("order", ORDERS)
def test_velocities_match_finite_differences(order: int) -> None:
    waypoints, durations, b = random_plan(np.random.default_rng(20 + order), 6)
    p = Preview(waypoints, durations, b, order)
    t, h = inside_samples(p), 1e-6
    np.testing.assert_allclose(
        p.dcm_velocity(t), (p.dcm(t + h) - p.dcm(t - h)) / (2 * h), atol=1e-6
    )
    np.testing.assert_allclose(
        p.vrp_velocity(t), (p.vrp(t + h) - p.vrp(t - h)) / (2 * h), atol=1e-6
    )
    for x in t[::4]:  # the scalar path agrees with the vectorised one
        np.testing.assert_allclose(p.dcm_velocity(float(x)), p.dcm_velocity(np.array([x]))[0])
        np.testing.assert_allclose(p.vrp_velocity(float(x)), p.vrp_velocity(np.array([x]))[0])
        np.testing.assert_allclose(p.dcm(float(x)), p.dcm(np.array([x]))[0], atol=1e-14)
        np.testing.assert_allclose(p.vrp(float(x)), p.vrp(np.array([x]))[0], atol=1e-14)


@pytest.mark.parametrize("order", ORDERS)
def test_terminal_constraint_eq_17(order: int) -> None:
    waypoints, durations, b = random_plan(np.random.default_rng(30 + order), 9)
    p = Preview(waypoints, durations, b, order)
    np.testing.assert_allclose(p.dcm(p.duration), waypoints[-1], atol=1e-12)
    np.testing.assert_allclose(p.xi_ref_T[-1], waypoints[-1], atol=0)
    np.testing.assert_allclose(p.dcm(np.array([p.duration]))[0], waypoints[-1], atol=1e-12)


# --- smoothness at phase boundaries (Table I) -----------------------------------------------------


def one_sided_derivatives(fun, t0: float, side: int, degree: int, h: float) -> np.ndarray:
    """Derivatives 0…degree at t0 from samples on one side only (polynomial fit = FD stencil)."""
    x = side * h * np.arange(1, 2 * degree + 4)
    y = fun(t0 + x)
    coefficients = np.polynomial.polynomial.polyfit(x, y, degree)  # exact for a polynomial
    factorials = np.array([np.prod(np.arange(1, k + 1)) for k in range(degree + 1)])
    return coefficients * factorials[:, None]


@pytest.mark.parametrize(("order", "smoothness"), [(1, 0), (3, 1), (5, 2)])
def test_vrp_smoothness_at_phase_boundaries(order: int, smoothness: int) -> None:
    waypoints, durations, b = random_plan(np.random.default_rng(40 + order), 6)
    durations = durations + 0.5
    p = Preview(waypoints, durations, b, order)
    h = 0.02
    for t0 in p.phase_start_times[1:]:
        left = one_sided_derivatives(p.vrp, t0, -1, order, h)
        right = one_sided_derivatives(p.vrp, t0, +1, order, h)
        scale = 10.0 ** np.arange(order + 1)
        np.testing.assert_allclose(
            left[: smoothness + 1] / scale[: smoothness + 1, None],
            right[: smoothness + 1] / scale[: smoothness + 1, None],
            atol=1e-7,
        )
        # and not one derivative more: Table I's order decides the smoothness
        jump = np.abs(left[smoothness + 1] - right[smoothness + 1]).max()
        assert jump > 1e-3


@pytest.mark.parametrize("order", ORDERS)
def test_dcm_continuous_at_phase_boundaries(order: int) -> None:
    waypoints, durations, b = random_plan(np.random.default_rng(50 + order), 8)
    p = Preview(waypoints, durations, b, order)
    for phi, t0 in enumerate(p.phase_start_times[1:]):
        left = p.dcm(np.nextafter(t0, -np.inf))
        np.testing.assert_allclose(left, p.dcm(float(t0)), atol=1e-9)
        np.testing.assert_allclose(p.dcm(float(t0)), p.xi_ref_0[phi + 1], atol=1e-12)
        np.testing.assert_allclose(p.xi_ref_T[phi], p.xi_ref_0[phi + 1], atol=0)  # (18)


# --- O(n) backward iteration vs dense eqs. (13)–(23) ------------------------------------------------


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("n_phases", [1, 2, 5, 31, 103])
def test_backward_iteration_matches_dense_eqs_20_21(order: int, n_phases: int) -> None:
    rng = np.random.default_rng(60 + n_phases + order)
    waypoints, durations, b = random_plan(rng, n_phases)
    p = Preview(waypoints, durations, b, order)
    dense = dense_matrices(durations, b, order)
    v_wp = waypoints.ravel()
    np.testing.assert_allclose(p.xi_ref_0.ravel(), dense["A_xi_ref_0"] @ v_wp, atol=1e-9)
    np.testing.assert_allclose(p.xi_ref_T.ravel(), dense["A_xi_ref_T"] @ v_wp, atol=1e-9)
    np.testing.assert_allclose(p.A_xi_ref_0, dense["A_xi_ref_0"], atol=1e-9)
    np.testing.assert_allclose(p.A_xi_ref_T, dense["A_xi_ref_T"], atol=1e-9)
    assert p.A_xi_ref_0.shape == (3 * n_phases, 3 * (n_phases + 1))
    np.testing.assert_allclose(np.kron(p.W_xi_ref_0, I3), dense["A_xi_ref_0"], atol=1e-9)
    np.testing.assert_allclose(np.kron(p.W_xi_ref_T, I3), dense["A_xi_ref_T"], atol=1e-9)


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("n_phases", [1, 4, 103])
def test_dcm_weights_match_dense_eqs_22_23(order: int, n_phases: int) -> None:
    rng = np.random.default_rng(70 + n_phases + order)
    waypoints, durations, b = random_plan(rng, n_phases)
    p = Preview(waypoints, durations, b, order)
    dense = dense_matrices(durations, b, order)
    t = np.concatenate([rng.uniform(0, p.duration, 25), p.phase_start_times[:3], [p.duration]])
    phases, t_local = p.phase_at(t)
    weights = p.dcm_weights(t)
    assert weights.shape == (t.size, n_phases + 1)
    for k, (phi, t_phi) in enumerate(zip(phases, t_local, strict=True)):
        a, be, g = phase_coefficients(durations[phi], b, order, t_phi)
        rows = slice(3 * phi, 3 * phi + 3)  # 3row(·, φ)
        A = (
            a * dense["A_v_ref_0"][rows]
            + be * dense["A_v_ref_T"][rows]
            + g * dense["A_xi_ref_T"][rows]
        )  # (23)
        np.testing.assert_allclose(np.kron(weights[k], I3), A, atol=1e-9)
        np.testing.assert_allclose(p.dcm_weights(float(t[k])), weights[k], atol=1e-12)
        np.testing.assert_allclose(p.dcm(float(t[k])), A @ waypoints.ravel(), atol=1e-9)  # (22)


# --- API contract ---------------------------------------------------------------------------------


def test_phase_at_boundaries_and_clamping() -> None:
    p = Preview(np.zeros((4, 3)), [0.5, 0.25, 1.0], 0.3, 5)
    assert p.duration == pytest.approx(1.75)
    np.testing.assert_array_equal(p.phase_start_times, [0.0, 0.5, 0.75])
    assert p.phase_at(0.5) == (1, 0.0)
    assert p.phase_at(0.75) == (2, 0.0)
    assert p.phase_at(1.75) == (2, 1.0)
    assert p.phase_at(10.0) == (2, 1.0)
    assert p.phase_at(-1.0) == (0, 0.0)
    assert p.phase_at(0.6) == (1, pytest.approx(0.1))
    phases, t_local = p.phase_at(np.array([-1.0, 0.0, 0.5, 0.6, 0.75, 1.75, 9.0]))
    np.testing.assert_array_equal(phases, [0, 0, 1, 1, 2, 2, 2])
    np.testing.assert_allclose(t_local, [0.0, 0.0, 0.0, 0.1, 0.0, 1.0, 1.0])


def test_shapes_clamping_and_scalar_types() -> None:
    waypoints, durations, b = random_plan(np.random.default_rng(3), 4)
    p = Preview(waypoints, durations, b, 3)
    for method in (p.vrp, p.dcm, p.dcm_velocity, p.vrp_velocity):
        assert method(0.3).shape == (3,)
        assert method(1).shape == (3,)
        assert method(np.float32(0.3)).shape == (3,)
        assert method(np.array(0.3)).shape == (3,)
        assert method(np.linspace(0, 1, 7)).shape == (7, 3)
        assert method([0.1, 0.2]).shape == (2, 3)
        np.testing.assert_array_equal(method(-5.0), method(0.0))
        np.testing.assert_array_equal(method(p.duration + 5.0), method(p.duration))
    assert p.dcm_weights(0.3).shape == (5,)
    assert p.xi_ref_0.shape == p.xi_ref_T.shape == (4, 3)
    assert p.n_phases == 4 and p.order == 3 and p.b == b
    np.testing.assert_array_equal(p.waypoints, waypoints)
    np.testing.assert_array_equal(p.durations, durations)


def test_preview_is_immutable_and_copies_its_input() -> None:
    waypoints, durations, b = random_plan(np.random.default_rng(4), 3)
    p = Preview(waypoints, durations, b, 5)
    before = p.dcm(0.2)
    waypoints[:] = 0.0
    durations[:] = 1.0
    np.testing.assert_array_equal(p.dcm(0.2), before)
    with pytest.raises(AttributeError):
        p.b = 0.5  # type: ignore[misc]
    for array in (p.waypoints, p.durations, p.xi_ref_0, p.xi_ref_T, p.W_xi_ref_0, p.A_xi_ref_0):
        with pytest.raises(ValueError):
            array[0] = 1.0


def test_with_waypoints_equals_a_fresh_preview() -> None:
    rng = np.random.default_rng(5)
    waypoints, durations, b = random_plan(rng, 6)
    p = Preview(waypoints, durations, b, 5)
    _ = p.W_xi_ref_0  # cached weights are reused, not recomputed
    new_waypoints = waypoints + rng.normal(0, 0.1, waypoints.shape)
    q = p.with_waypoints(new_waypoints)
    fresh = Preview(new_waypoints, durations, b, 5)
    t = np.linspace(0, p.duration, 101)
    np.testing.assert_allclose(q.dcm(t), fresh.dcm(t), atol=1e-14)
    np.testing.assert_allclose(q.vrp(t), fresh.vrp(t), atol=1e-14)
    np.testing.assert_allclose(q.xi_ref_0, q.W_xi_ref_0 @ new_waypoints, atol=1e-12)
    np.testing.assert_array_equal(p.waypoints, waypoints)
    with pytest.raises(ValueError, match="waypoints"):
        p.with_waypoints(new_waypoints[:-1])


# --- validation -------------------------------------------------------------------------------------

GOOD_WAYPOINTS = np.zeros((4, 3))
GOOD_DURATIONS = [0.5, 0.2, 0.7]


@pytest.mark.parametrize(
    ("waypoints", "durations", "b", "order", "pattern"),
    [
        (GOOD_WAYPOINTS, [0.5, 0.0, 0.7], 0.3, 5, r"durations\[1\] = 0\.0: .*> 0 s"),
        (GOOD_WAYPOINTS, [0.5, 0.2, -0.1], 0.3, 5, r"durations\[2\] = -0\.1: .*> 0 s"),
        (GOOD_WAYPOINTS, [0.5, np.nan, 0.7], 0.3, 5, r"durations\[1\] = nan"),
        (GOOD_WAYPOINTS, [np.inf, 0.2, 0.7], 0.3, 5, r"durations\[0\] = inf"),
        (GOOD_WAYPOINTS, [[0.5, 0.2, 0.7]], 0.3, 5, r"durations has shape \(1, 3\)"),
        (GOOD_WAYPOINTS, [], 0.3, 5, r"durations has shape \(0,\)"),
        (GOOD_WAYPOINTS, ["a", 0.2, 0.7], 0.3, 5, r"durations = "),
        (GOOD_WAYPOINTS, GOOD_DURATIONS, 0.0, 5, r"b = 0\.0: .*> 0 s"),
        (GOOD_WAYPOINTS, GOOD_DURATIONS, -0.3, 5, r"b = -0\.3"),
        (GOOD_WAYPOINTS, GOOD_DURATIONS, np.nan, 5, r"b = nan"),
        (GOOD_WAYPOINTS, GOOD_DURATIONS, np.inf, 5, r"b = inf"),
        (GOOD_WAYPOINTS, GOOD_DURATIONS, "0.3", 5, r"b = '0\.3'"),
        (GOOD_WAYPOINTS, GOOD_DURATIONS, 0.3, 2, r"order = 2: .*0, 1, 3, 5"),
        (GOOD_WAYPOINTS, GOOD_DURATIONS, 0.3, 4, r"order = 4"),
        (GOOD_WAYPOINTS, GOOD_DURATIONS, 0.3, 3.5, r"order = 3\.5"),
        (np.zeros((4, 2)), GOOD_DURATIONS, 0.3, 5, r"waypoints has shape \(4, 2\).*\(n, 3\)"),
        (np.zeros(12), GOOD_DURATIONS, 0.3, 5, r"waypoints has shape \(12,\)"),
        (np.zeros((5, 3)), GOOD_DURATIONS, 0.3, 5, r"waypoints has 5 rows but durations has 3"),
        (np.zeros((3, 3)), GOOD_DURATIONS, 0.3, 5, r"waypoints has 3 rows but durations has 3"),
        (np.zeros((1, 3)), [0.5], 0.3, 5, r"waypoints has 1 row.*at least 2"),
        (np.zeros((0, 3)), [0.5], 0.3, 5, r"waypoints has 0 row.*at least 2"),
        ([[0, 0, 0], [1, np.nan, 0]], [0.5], 0.3, 5, r"waypoints\[1, 1\] = nan.*finite"),
        ([[0, 0, np.inf], [1, 0, 0]], [0.5], 0.3, 5, r"waypoints\[0, 2\] = inf.*finite"),
    ],
)
def test_bad_input_raises_value_error_naming_the_argument(
    waypoints, durations, b, order, pattern
) -> None:
    with pytest.raises(ValueError, match=pattern):
        Preview(waypoints, durations, b, order)


@pytest.mark.parametrize("method", ["vrp", "dcm", "dcm_velocity", "vrp_velocity", "dcm_weights"])
def test_nan_time_raises(method: str) -> None:
    p = Preview(GOOD_WAYPOINTS, GOOD_DURATIONS, 0.3, 5)
    with pytest.raises(ValueError, match=r"t = nan"):
        getattr(p, method)(float("nan"))
    with pytest.raises(ValueError, match=r"t\[1\] = nan"):
        getattr(p, method)(np.array([0.1, np.nan]))
    with pytest.raises(ValueError, match=r"t has shape \(2, 2\)"):
        getattr(p, method)(np.zeros((2, 2)))
    with pytest.raises(ValueError, match=r"t = nan"):
        p.phase_at(float("nan"))


# --- short phases (T ≪ b): no cancellation (issue 9) ------------------------------------------

# phases of 1 ms, the schema limit 0.02 s and ordinary ones, with b = 0.6 s: every order has
# phases sampled in closed form and phases sampled by the series of β
SHORT_DURATIONS = np.array([0.7, 1e-3, 1e-3, 0.02, 1e-3, 0.3, 0.02, 1e-3, 1.5, 1e-3])
SHORT_B = 0.6


def short_plan(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.0, 1.0, (SHORT_DURATIONS.size + 1, 3)), SHORT_DURATIONS


@pytest.mark.parametrize("order", ORDERS)
def test_short_phases_match_eq_10_in_exact_arithmetic(order: int) -> None:
    """ξ_ref(t) and the weights of eqs. (22), (23) against eq. (10) with α, β, γ in exact
    arithmetic and the dense eqs. (20), (21), at phases of 1 ms and 20 ms with b = 0.6 s."""
    waypoints, durations = short_plan(80 + order)
    p = Preview(waypoints, durations, SHORT_B, order)
    if order:
        assert p._schedule.closed_form.any() and not p._schedule.closed_form.all()
    dense = dense_matrices(durations, SHORT_B, order)
    np.testing.assert_allclose(
        p.xi_ref_T.ravel(), dense["A_xi_ref_T"] @ waypoints.ravel(), atol=1e-14
    )
    fractions = np.array([0.0, 0.13, 0.5, 0.77, 0.999])
    t = (p.phase_start_times[:, None] + durations[:, None] * fractions).ravel()
    phases, t_local = p.phase_at(t)
    expected = np.empty((t.size, 3))
    for k, (phi, t_phi) in enumerate(zip(phases, t_local, strict=True)):
        a, be, g = phase_coefficients(durations[phi], SHORT_B, order, t_phi)
        rows = slice(3 * phi, 3 * phi + 3)
        A = (
            a * dense["A_v_ref_0"][rows]
            + be * dense["A_v_ref_T"][rows]
            + g * dense["A_xi_ref_T"][rows]
        )
        expected[k] = A @ waypoints.ravel()
        np.testing.assert_allclose(np.kron(p.dcm_weights(float(t[k])), I3), A, atol=1e-14)
        np.testing.assert_allclose(p.dcm(float(t[k])), expected[k], atol=1e-14)
    np.testing.assert_allclose(p.dcm(t), expected, atol=1e-14)
    np.testing.assert_allclose(p.dcm_weights(t) @ waypoints, expected, atol=1e-14)


@pytest.mark.parametrize("order", ORDERS)
def test_short_phases_dcm_is_continuous_at_boundaries(order: int) -> None:
    """At every boundary of 1-ms and 20-ms phases, ξ_ref from the left (the last float before
    the boundary) equals ξ_ref from the right to ~1e-15 m; both equal ξ_ref_T = ξ_ref_0 (18)."""
    waypoints, durations = short_plan(90 + order)
    p = Preview(waypoints, durations, SHORT_B, order)
    boundaries = p.phase_start_times[1:]
    left = p.dcm(np.nextafter(boundaries, -np.inf))
    right = p.dcm(boundaries)
    np.testing.assert_allclose(left, right, atol=1e-14)
    np.testing.assert_allclose(left, p.xi_ref_T[:-1], atol=1e-14)
    np.testing.assert_allclose(right, p.xi_ref_0[1:], atol=1e-14)
    for t0 in boundaries:
        np.testing.assert_allclose(
            p.dcm(float(np.nextafter(t0, -np.inf))), p.dcm(float(t0)), atol=1e-14
        )


def central_difference(fun, t: np.ndarray, h: float) -> np.ndarray:
    """Fourth-order central difference (error h⁴ f⁽⁵⁾ / 30)."""
    return (-fun(t + 2 * h) + 8 * fun(t + h) - 8 * fun(t - h) + fun(t - 2 * h)) / (12 * h)


@pytest.mark.parametrize("order", ORDERS)
def test_short_phases_satisfy_eq_6_by_finite_differences(order: int) -> None:
    """ξ̇ = (ξ − v)/b (6) inside phases of 1 ms and 20 ms (b = 0.6 s), and dcm_velocity agrees;
    h = 1 µs: truncation ~1e-11 m/s, rounding (ξ to ~5e-15 m) ~1e-8 m/s."""
    waypoints, durations = short_plan(100 + order)
    p = Preview(waypoints, durations, SHORT_B, order)
    t = inside_samples(p, per_phase=7, margin=0.1)
    derivative = central_difference(p.dcm, t, 1e-6)
    np.testing.assert_allclose(derivative, (p.dcm(t) - p.vrp(t)) / SHORT_B, atol=2e-8)
    np.testing.assert_allclose(p.dcm_velocity(t), derivative, atol=2e-8)
    for x in t[::5]:
        np.testing.assert_allclose(
            p.dcm_velocity(float(x)), p.dcm_velocity(np.array([x]))[0], atol=1e-13
        )


def test_with_waypoints_reuses_the_short_phase_series() -> None:
    waypoints, durations = short_plan(7)
    p = Preview(waypoints, durations, SHORT_B, 5)
    new = waypoints[::-1].copy()
    t = np.linspace(0.0, p.duration, 301)
    np.testing.assert_allclose(
        p.with_waypoints(new).dcm(t), Preview(new, durations, SHORT_B, 5).dcm(t), atol=0
    )
