"""The session's seams: the per-tick record, live gains, the plan walked, the plant's own height."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from dcmviz import GRAVITY
from dcmviz.config import Config
from dcmviz.robots import load_robot
from dcmviz.session import Session
from dcmviz.session.tick import Tick


def lip(**sections) -> Session:
    return Session(Config().replace(sim={"backend": "lip"}, **sections), backend="lip")


def test_tick_record_matches_the_walk() -> None:
    s = lip()
    ticks: list[Tick] = []
    s.subscribe(ticks.append)
    s.run(3.0)
    assert len(ticks) == s.metrics.ticks and ticks[-1] is s.tick()
    t = np.array([k.t for k in ticks])
    np.testing.assert_allclose(np.diff(t), s.backend.control_dt, atol=1e-12)  # no drift
    last = ticks[-1]
    e = last.command.xi - last.command.xi_ref
    assert last.dcm_error_m == pytest.approx(float(np.sqrt(e @ e)), abs=1e-15)
    assert last.plan is s.plan and last.robot.name == "talos" and last.backend == "lip"
    versions = sorted({k.plan_version for k in ticks})
    assert versions == list(range(versions[0], versions[0] + len(versions)))  # +1 per change


def test_live_gain_change_keeps_the_walk_going() -> None:
    s = lip()
    s.run(2.0)
    t, plan, steps = s.t, s.plan, s.steps_completed
    note = s.set_config(s.config.replace(control={"k_xi": 5.0}))
    assert note == "gains changed (walk continues)"
    assert s.t == t and s.plan is plan and s.steps_completed == steps  # no restart
    s.step()
    # eq. (24)/(41) with the new gain, computed here from the record of that tick
    c = s.tick().command
    expected = c.v_ref + (1.0 + 5.0 * s.config.dcm.b) * (c.xi - c.xi_adj)
    np.testing.assert_allclose(c.v_cmd, expected, atol=1e-12)
    # anything else restarts and says what changed
    note = s.set_config(s.config.replace(gait={"t_ss": 0.8}))
    assert note == "restarted: gait changed" and s.t == 0.0


def test_observer_switched_on_starts_from_the_present_momentum() -> None:
    s = lip(control={"observer": False})
    s.push((0.0, 60.0, 0.0), duration=5.0, start=1.0)
    s.run(1.5)  # moving sideways under the push
    s.set_config(s.config.replace(control={"observer": True}))
    s.step()
    # eq. (43)–(45) after one tick from p̂ = m ẋ: F̂ is one tick's worth, not a jump to m ẋ k_F
    f_hat = s.tick().f_hat
    assert np.linalg.norm(f_hat) < 0.2 * 60.0
    s.run(1.0)
    assert s.tick().f_hat[1] == pytest.approx(60.0, rel=0.05)  # and converges to the push


def test_point_mass_stands_at_the_robots_height_whatever_b() -> None:
    spec = load_robot("talos").spec
    for b in (0.275, 0.30):  # CoM 0.742 m and 0.883 m, the robot stands at 0.877 m
        s = lip(dcm={"order": 5, "b": b})
        assert s.t == 0.0 and s.last_state.com[2] == pytest.approx(spec.com_height_m)
        s.step()
        c = s.tick().command
        # the reference starts where the robot is (no vertical jump) ...
        assert abs(c.xi_ref[2] - spec.com_height_m) < 1e-3
        s.run(s.plan.duration + 1.0)
        # ... and ends with the CoM g b² above the feet, as the controller asks
        assert s.last_state.com[2] == pytest.approx(GRAVITY * b * b, abs=2e-3)
        assert not s.fell


def test_csv_has_one_row_per_tick(tmp_path) -> None:
    from dcmviz.run import CSV_COLUMNS, main

    out = tmp_path / "walk.csv"
    assert (
        main(["presets/walk_forward.toml", "--sim", "lip", "--duration", "2", "--csv", str(out)])
        == 0
    )
    with out.open() as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0]) == CSV_COLUMNS
    assert len(rows) == round(2.0 / 0.005)
    t = np.array([float(r["t"]) for r in rows])
    assert t[0] == 0.0 and math.isclose(t[-1], 2.0 - 0.005, abs_tol=1e-9)
    supports = {r["support"] for r in rows}
    assert (
        "double" in supports
        and supports & {"left", "right"}
        and supports <= {"double", "left", "right"}
    )
    xi = np.array([[float(r[f"xi_{a}"]) for a in "xyz"] for r in rows])
    com = np.array([[float(r[f"com_{a}"]) for a in "xyz"] for r in rows])
    # ξ = x + b ẋ (eq. 1): with ẋ from finite differences of the CoM column
    b = 0.30
    v = np.gradient(com, 0.005, axis=0)
    np.testing.assert_allclose(xi[1:-1, :2], (com + b * v)[:-2, :2], atol=2e-3)
