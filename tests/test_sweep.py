"""Push-recovery sweep: boundary search, the recovery issue's ratio target, outputs, CLI errors."""

from __future__ import annotations

import csv
import dataclasses
import functools
import json
import math
from pathlib import Path

import pytest

from dcmviz.config import load_preset
from dcmviz.sweep import (
    SweepSettings,
    envelope,
    find_boundary,
    main,
    push_window,
    table,
    write_envelope,
)
from dcmviz.sweep.bounds import footstep_bound_at, stance_edge_bound
from dcmviz.sweep.experiments import stance_edge_bounds

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "presets" / "walk_forward.toml"


def test_find_boundary_against_known_threshold() -> None:
    calls: list[float] = []

    def ok(x: float) -> bool:
        calls.append(x)
        return x <= 37.3

    b = find_boundary(ok, 150.0, grid=6, iterations=8)
    assert b.max_ok <= 37.3 < b.first_fail
    assert b.first_fail - b.max_ok == pytest.approx(25.0 / 2**8)
    assert b.non_monotone == [] and not b.capped and b.runs == len(calls) == 6 + 8


def test_find_boundary_reports_non_monotone_and_cap() -> None:
    b2 = find_boundary(lambda x: x < 30.0 or 75.0 < x < 85.0, 100.0, grid=5, iterations=4)
    assert b2.non_monotone == [80.0]  # grid 20, 40, 60, 80, 100: 40 falls, 80 survives
    assert 20.0 <= b2.max_ok < 30.0 <= b2.first_fail <= 40.0  # the first boundary is reported
    capped = find_boundary(lambda x: True, 50.0, grid=3, iterations=4)
    assert capped.capped and capped.max_ok == 50.0


def test_push_window_is_mid_single_support() -> None:
    config = load_preset(WALK)
    start, t_lift, t_touch = push_window(config, 4, 0.5)
    g = config.gait
    # stand phase t_start, then three steps of t_ss + t_ds before the 4th lift-off
    assert t_lift == pytest.approx(g.t_start + 3 * (g.t_ss + g.t_ds))
    assert t_touch - t_lift == pytest.approx(g.t_ss)
    assert start == pytest.approx(t_lift + 0.5 * g.t_ss)


def test_step_adjustment_recovers_larger_lateral_impulse(tmp_path: Path) -> None:
    """Recovery issue: step adjustment ≥ 1.8× the lateral impulse of tracking alone.

    The 4th step swings the right foot, so a −y push (270°) is caught by that foot; a +y push
    (90°) would need the legs to cross and is only caught one step later (see the report).
    """
    settings = SweepSettings(
        backend="lip",
        angles_deg=(90.0, 270.0),
        controllers=("tracking", "step_adjustment"),
        max_impulse_ns=120.0,
        grid=4,
        iterations=4,
        jobs=1,
    )
    result = envelope(load_preset(WALK), settings)
    assert result["swing_side"] == "right"
    j = {(r["direction_deg"], r["controller"]): r["max_impulse_ns"] for r in result["rows"]}
    res = result["resolution_ns"]
    assert res == pytest.approx(120.0 / 4 / 16)
    # tracking alone: a point-mass capture estimate gives ~20-30 N·s for Talos (DESIGN.md: 22)
    assert 15.0 < j[(270.0, "tracking")] < 40.0
    assert j[(270.0, "step_adjustment")] >= 1.8 * (j[(270.0, "tracking")] + res)
    assert j[(90.0, "step_adjustment")] >= j[(90.0, "tracking")] - res
    for r in result["rows"]:
        assert r["max_force_n"] == pytest.approx(r["max_impulse_ns"] / 0.2)

    paths = write_envelope(result, tmp_path)
    assert [p.name for p in paths] == ["envelope.json", "envelope.csv", "envelope.png"]
    rows = list(csv.DictReader(paths[1].open()))
    assert len(rows) == 4 and {"direction_deg", "controller", "max_impulse_ns"} <= set(rows[0])
    assert json.loads(paths[0].read_text())["rows"][0]["controller"] in settings.controllers
    assert paths[2].stat().st_size > 10_000


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--phase", "1.5"], "--phase"),
        (["--directions", "0"], "--directions"),
        (["--step", "40"], "--step"),
        (["--controllers", "tracking,magic"], "magic"),
        (["--sim", "ode"], "--sim"),
        (["--address", "127.0.0.1:6379", "--jobs", "2"], "--jobs"),
        (["--grid", "6"], "--coarse"),
        (["--strategies", "next_step,magic"], "magic"),
        (["--strategies", "multi_step", "--controllers", "tracking"], "--strategies"),
    ],
)
def test_bad_input_exits_2(capsys, args, needle) -> None:
    assert main([str(WALK), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err


def test_ramp_test_needs_a_ramped_push(capsys, tmp_path: Path) -> None:
    assert main([str(WALK), "--ramp-test", "--out", str(tmp_path)]) == 2
    assert "ramp" in capsys.readouterr().err


def test_strategies_side_by_side(tmp_path: Path) -> None:
    """--strategies: tracking and each recovery strategy (step adjustment on, observer off) in
    one table and one polar plot; towards the stance foot (90°) step timing catches more."""
    settings = SweepSettings(
        backend="lip",
        angles_deg=(90.0,),
        controllers=("tracking", "next_step", "multi_step_timing"),
        max_impulse_ns=60.0,
        grid=3,
        iterations=3,
        jobs=1,
    )
    result = envelope(load_preset(WALK), settings)
    j = {r["controller"]: r["max_impulse_ns"] for r in result["rows"]}
    res = result["resolution_ns"]
    assert j["multi_step_timing"] >= j["next_step"] + res
    assert j["next_step"] >= j["tracking"] - res
    text = table(result)
    assert "multi_step_timing/trk" in text and "next_step/trk" in text
    # and how much of the stance-edge bound each reaches (none beyond it)
    bound = result["stance_edge_bound_ns"]["90.0"]
    share = {n: round(100 * v / bound) for n, v in j.items()}
    assert all(v <= 100 for v in share.values())
    assert (
        "  90°: " + ", ".join(f"{n} {share[n]} %" for n in j) + " of the stance-edge bound" in text
    )
    # the point mass is pushed at its CoM: no bound with the trunk taking the moment
    assert result["stance_edge_bound_trunk_ns"] == {}
    assert "taken by the trunk" not in text
    # a humanoid's envelope prints both (the lever counted and not): Talos's numbers
    humanoid = dataclasses.replace(settings, backend="mujoco")
    config = load_preset(WALK)
    trunk = stance_edge_bounds(
        config, humanoid, functools.partial(stance_edge_bound, moment_at_feet=False)
    )
    torso = stance_edge_bounds(config, humanoid)
    assert trunk == stance_edge_bounds(config, settings)  # the point mass's, pushed at its CoM
    assert trunk["90.0"] > 1.3 * torso["90.0"]  # Talos: 41.8 against 29.3 N·s
    text = table({**result, "stance_edge_bound_ns": torso, "stance_edge_bound_trunk_ns": trunk})
    assert f"by the feet: 90° {trunk['90.0']:.1f} N·s" in text
    # stepping the stance foot out once the other is down: above the stance-edge bound (the CoP
    # on the other sole meanwhile), below the footstep bound (the CoP kept on the lifted sole)
    swung = result["swing_bound_ns"]["90.0"]
    start = push_window(config, settings.step, settings.phase)[0]
    loose = footstep_bound_at(config, start, settings.push_duration_s, math.pi / 2,
                              crossing=False)  # fmt: skip
    assert result["stance_edge_bound_ns"]["90.0"] < swung < 0.8 * loose
    assert f"swings as the walker's: swing_bound_at) at most: 90° {swung:.1f} N·s" in table(result)
    paths = write_envelope(result, tmp_path)
    assert paths[2].stat().st_size > 10_000


@pytest.mark.parametrize("backend", ["lip", "mujoco"])
def test_a_rollout_from_the_prefix_snapshot_equals_one_that_walks_there(backend: str) -> None:
    """The humanoid's rollouts continue from the trial's pickled state at the push start
    (prefix_snapshot; the whole session, pickled before, was refused for MuJoCo, so every
    humanoid rollout walked its 4 s prefix again): the same survival, fall time and largest DCM
    error as a rollout that walks the prefix itself, for a push it survives and one it does
    not."""
    from dcmviz.sweep.search import Trial, prefix_snapshot, rollout
    from dcmviz.sweep.search import push_window as window

    config = load_preset(Path(__file__).resolve().parents[1] / "presets" / "walk_forward.toml")
    config = config.replace(pushes=[], control={"step_adjustment": True})
    start, _, end = window(config, 4, 0.5)
    trial = Trial(config, backend, start, 0.2, end + 1.0)
    snapshot = prefix_snapshot(trial)
    assert snapshot is not None  # (None for MuJoCo before: no prefix was shared)
    outcomes = []
    for impulse in (10.0, 60.0):
        force = (0.0, impulse / 0.2, 0.0)
        a, b = rollout(trial, snapshot, force), rollout(trial, None, force)
        assert (a.survived, a.fall_time_s, a.max_dcm_error_m) == (
            b.survived, b.fall_time_s, b.max_dcm_error_m
        )  # fmt: skip
        outcomes.append(a.survived)
    assert outcomes == [True, False]


def test_the_sweep_bench_compares_checkouts_in_processes_of_their_own(tmp_path: Path) -> None:
    """``bench/sweep.py --vs``: each rate comes from a process that imports the given checkout's
    dcmviz (asserted there) and runs the QUICK envelope, 4 directions × (6 + 2) probes = 32
    rollouts; a path that is no checkout is refused with the flag named."""
    import importlib.util
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location("sweep_bench", root / "bench" / "sweep.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    rate, n, wall = bench.serial_rate_of(root, str(root / "presets" / "walk_forward.toml"), "lip")
    assert n == 32 and rate == pytest.approx(n / wall, rel=1e-9)
    out = subprocess.run([sys.executable, str(root / "bench" / "sweep.py"), "--vs", str(tmp_path)],
                         capture_output=True, text=True)  # fmt: skip
    assert out.returncode == 2 and "--vs" in out.stderr and "dcmviz checkout" in out.stderr
