"""Headless runner (DESIGN.md "Headless runner"): JSON fields, exit codes, --set."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dcmviz.config import Push
from dcmviz.run import main, push_recovery

ROOT = Path(__file__).resolve().parents[1]
PRESETS = ROOT / "presets"
REQUIRED = {
    "fell": bool,
    "sim_time_s": float,
    "wall_time_s": float,
    "real_time_factor": float,
    "steps_completed": int,
    "max_dcm_error_m": float,
    "final_dcm_error_m": float,
    "step_adjustments": list,
    "backend": str,
    "robot": str,
}


def run_json(tmp_path: Path, *args: str) -> dict:
    out = tmp_path / "result.json"
    assert main([*args, "--json", str(out)]) == 0
    return json.loads(out.read_text())


def test_walk_forward_lip_fields_and_values(tmp_path: Path, capsys) -> None:
    res = run_json(tmp_path, str(PRESETS / "walk_forward.toml"), "--sim", "lip")
    for key, kind in REQUIRED.items():
        assert isinstance(res[key], kind), key
    assert "fall_time_s" in res and res["fall_time_s"] is None
    assert res["fell"] is False
    assert res["backend"] == "lip" and res["robot"] == "talos"
    assert res["steps_completed"] == 10 == res["steps_planned"]
    assert res["sim_time_s"] == pytest.approx(14.0, abs=0.01)  # the preset's sim.duration
    assert res["real_time_factor"] == pytest.approx(res["sim_time_s"] / res["wall_time_s"])
    assert res["max_dcm_error_m"] < 1e-3  # undisturbed: the walk is nominal
    assert res["step_adjustments"] == []
    assert "walked without falling" in capsys.readouterr().out


def test_duration_and_lateral_push_recovery(tmp_path: Path) -> None:
    res = run_json(tmp_path, str(PRESETS / "lateral_push.toml"), "--sim", "lip", "--duration", "12")
    assert res["sim_time_s"] == pytest.approx(12.0, abs=0.01)
    assert not res["fell"]
    assert len(res["step_adjustments"]) >= 2
    for adj in res["step_adjustments"]:
        assert set(adj) >= {"t", "dx", "dy"}
    # the first push (+y) moves a footstep to +y, the second (−y) to −y
    assert max(a["dy"] for a in res["step_adjustments"]) > 0.02
    assert min(a["dy"] for a in res["step_adjustments"]) < -0.02
    for push in res["pushes"]:
        assert push["max_dcm_error_m"] > 0.02
        assert push["recovery_steps_1cm"] is not None and push["recovery_steps_1cm"] <= 3


def test_set_observer_changes_tug_of_war(tmp_path: Path) -> None:
    preset = str(PRESETS / "tug_of_war.toml")
    with_observer = run_json(tmp_path, preset, "--sim", "lip")
    without = run_json(tmp_path, preset, "--sim", "lip", "--set", "control.observer=false")
    assert with_observer["fell"] is False
    assert without["fell"] is True and without["fall_time_s"] > 1.5
    assert without["control"]["observer"] is False


def test_push_recovery_against_hand_made_trace() -> None:
    t = np.arange(0.0, 10.0, 0.01)
    error = np.where((t >= 2.0) & (t < 5.0), 0.05 * np.exp(-(t - 2.0)), 0.0)
    push = Push(start=2.0, duration=0.5, force=(0.0, 40.0, 0.0))
    (res,) = push_recovery([push], t, error, touchdowns=[2.9, 3.8, 4.7], fall_time_s=None)
    assert res["max_dcm_error_during_push_m"] == pytest.approx(0.05)
    assert res["impulse_ns"] == pytest.approx(20.0)
    # 0.05 e^{-(t-2)} < 0.01 for t > 2 + ln 5 = 3.609 s, i.e. 1.109 s after the push ended
    assert res["recovery_time_1cm_s"] == pytest.approx(np.log(5.0) + 1.5 - 2.0, abs=0.011)
    assert res["recovery_steps_1cm"] == 1
    assert res["recovery_time_2cm_s"] == pytest.approx(np.log(2.5) - 0.5, abs=0.011)
    fell = push_recovery([push], t, error, touchdowns=[], fall_time_s=3.0)[0]
    assert fell["recovery_time_1cm_s"] is None


BAD_INPUTS = [
    (["nope.toml"], "does not exist"),
    (["{p}", "--sim", "bullet"], "--sim"),
    (["{p}", "--duration", "0"], "--duration"),
    (["{p}", "--duration", "-2"], "--duration"),
    (["{p}", "--set", "control.nope=1"], "control.nope"),
    (["{p}", "--set", "dcm.b"], "dcm.b"),
    (["{p}", "--set", "dcm.b=0.31x"], "TOML literal"),
    (["{p}", "--set", "dcm.b=5"], "dcm.b"),
    (["{bad}"], "not valid TOML"),
    (["{unknown}"], "gait.stride"),
]


@pytest.mark.parametrize(("args", "needle"), BAD_INPUTS)
def test_bad_input_exits_2_with_one_line(tmp_path: Path, capsys, args, needle) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\n[gait\n')
    unknown = tmp_path / "unknown.toml"
    unknown.write_text('name = "x"\n[gait]\nstride = 0.2\n')
    fmt = {"p": str(PRESETS / "walk_forward.toml"), "bad": str(bad), "unknown": str(unknown)}
    argv = [a.format(**fmt) for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("dcmviz.run: error:")
    assert needle in err


def test_real_cli_bad_input_and_success(tmp_path: Path) -> None:
    bad = subprocess.run(
        [sys.executable, "-m", "dcmviz.run", str(PRESETS / "walk_forward.toml"), "--sim", "x"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert bad.returncode == 2
    assert len(bad.stderr.strip().splitlines()) == 1 and "--sim" in bad.stderr
    out = tmp_path / "r.json"
    ok = subprocess.run(
        [
            sys.executable,
            "-m",
            "dcmviz.run",
            str(PRESETS / "walk_forward.toml"),
            "--sim",
            "lip",
            "--duration",
            "3",
            "--json",
            str(out),
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert ok.returncode == 0, ok.stderr
    assert json.loads(out.read_text())["sim_time_s"] == pytest.approx(3.0, abs=0.01)
