"""Standing-to-walking continuity, D1–D3 and eqs. (25), (26), against a dense solve."""

import numpy as np
import pytest
from dcm_reference import dense_matrices

from dcmviz.dcm import Preview, continuity_matrix, continuity_waypoints

ORDERS = (0, 1, 3, 5)
I3 = np.eye(3)


def dense_B_wp(durations: np.ndarray, b: float, order: int) -> np.ndarray:
    """B_wp of eq. (25), block row by block row."""
    n_wp = len(durations) + 1
    B = np.zeros((3 * n_wp, 3 * n_wp))
    B[0:3, 0:3] = I3  # D1
    B[3:6] = dense_matrices(durations, b, order)["A_xi_ref_0"][0:3]  # D2: 3row(A_xi_ref_0, 1)
    B[6:-3, 6:-3] = np.eye(3 * (n_wp - 3))  # v_wp,uc
    B[-3:, -3:] = I3  # D3
    return B


def random_problem(rng: np.random.Generator, n_phases: int):
    v_stand_ini = rng.uniform(-1, 1, 3)
    v_stand_end = rng.uniform(-1, 1, 3)
    v_uc = rng.uniform(-1, 1, (n_phases - 2, 3))
    durations = rng.uniform(0.1, 1.0, n_phases)
    b = rng.uniform(0.2, 0.5)
    return v_stand_ini, v_uc, v_stand_end, durations, b


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("n_phases", [2, 3, 8, 41, 103])
def test_d1_d2_d3_hold_and_match_dense_solve(order: int, n_phases: int) -> None:
    rng = np.random.default_rng(n_phases * 7 + order)
    v_stand_ini, v_uc, v_stand_end, durations, b = random_problem(rng, n_phases)
    v_wp = continuity_waypoints(v_stand_ini, v_uc, v_stand_end, durations, b, order)
    assert v_wp.shape == (n_phases + 1, 3)

    p = Preview(v_wp, durations, b, order)
    np.testing.assert_allclose(v_wp[0], v_stand_ini, atol=1e-9)  # D1
    np.testing.assert_allclose(p.xi_ref_0[0], v_stand_ini, atol=1e-9)  # D2
    np.testing.assert_allclose(p.dcm(0.0), v_stand_ini, atol=1e-9)
    np.testing.assert_allclose(v_wp[-1], v_stand_end, atol=1e-9)  # D3
    np.testing.assert_allclose(p.dcm(p.duration), v_stand_end, atol=1e-9)  # (17) + D3
    np.testing.assert_allclose(v_wp[2:-1], v_uc, atol=0)

    B_wp = dense_B_wp(durations, b, order)
    b_wp = np.concatenate([v_stand_ini, v_stand_ini, v_uc.ravel(), v_stand_end])  # (25)
    np.testing.assert_allclose(v_wp.ravel(), np.linalg.solve(B_wp, b_wp), atol=1e-9)  # (26)
    np.testing.assert_allclose(continuity_matrix(durations, b, order), B_wp, atol=1e-9)


def test_dcm_starts_at_rest() -> None:
    """With D1 and D2 the DCM reference velocity is zero at the start (ξ = v, eq. 3)."""
    v_stand_ini, v_uc, v_stand_end, durations, b = random_problem(np.random.default_rng(1), 6)
    v_wp = continuity_waypoints(v_stand_ini, v_uc, v_stand_end, durations, b, 5)
    p = Preview(v_wp, durations, b, 5)
    np.testing.assert_allclose(p.dcm_velocity(0.0), 0.0, atol=1e-9)
    np.testing.assert_allclose(p.dcm_velocity(p.duration), 0.0, atol=1e-9)


def test_empty_v_uc_for_three_waypoints() -> None:
    v_wp = continuity_waypoints([0, 0, 0.9], [], [0.1, 0, 0.9], [0.5, 0.5], 0.3, 3)
    assert v_wp.shape == (3, 3)
    v_wp = continuity_waypoints([0, 0, 0.9], np.zeros((0, 3)), [0.1, 0, 0.9], [0.5, 0.5], 0.3, 3)
    assert v_wp.shape == (3, 3)


@pytest.mark.parametrize(
    ("kwargs", "pattern"),
    [
        (dict(durations=[0.5]), r"durations has 1 entry.*at least 2"),
        (dict(durations=[0.5, -0.2, 0.5]), r"durations\[1\] = -0\.2"),
        (dict(durations=[0.5, 0.2, np.nan]), r"durations\[2\] = nan"),
        (dict(b=0.0), r"b = 0\.0"),
        (dict(order=2), r"order = 2"),
        (dict(v_stand_ini=[0, 0]), r"v_stand_ini has shape \(2,\).*\(3,\)"),
        (dict(v_stand_ini=[0, np.nan, 0]), r"v_stand_ini\[1\] = nan"),
        (dict(v_stand_end=[0, 0, np.inf]), r"v_stand_end\[2\] = inf"),
        (dict(v_uc=np.zeros((2, 3))), r"v_uc has shape \(2, 3\).*\(1, 3\)"),
        (dict(v_uc=np.zeros((1, 2))), r"v_uc has shape \(1, 2\)"),
        (dict(v_uc=[[0, np.nan, 0]]), r"v_uc\[0, 1\] = nan"),
    ],
)
def test_bad_input_raises_value_error_naming_the_argument(kwargs: dict, pattern: str) -> None:
    arguments = dict(
        v_stand_ini=[0, 0, 0.9],
        v_uc=[[0.2, 0.1, 0.9]],
        v_stand_end=[0.4, 0, 0.9],
        durations=[0.5, 0.2, 0.5],
        b=0.3,
        order=5,
    )
    arguments.update(kwargs)
    with pytest.raises(ValueError, match=pattern):
        continuity_waypoints(**arguments)
