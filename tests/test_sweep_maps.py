"""Gain maps (--grid) and the sweep CLI's resume, on the serial path (no Ray): the map's values
against envelopes of the overridden presets, its files, bad --grid input."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from dcmviz.config import load_preset
from dcmviz.sweep import SweepSettings, envelope, envelope_metric, main

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT / "presets" / "walk_forward.toml"
COARSE = ["--sim", "lip", "--coarse", "3", "--iterations", "2", "--jobs", "1", "--no-progress"]


def test_map_values_are_the_envelopes_of_the_grid_points(tmp_path: Path, capsys) -> None:
    args = [str(WALK), *COARSE, "--directions", "2", "--out", str(tmp_path)]
    grid = ["--grid", "control.k_xi=2:6:2", "dcm.b=0.28:0.3:2"]
    assert main([*args, *grid]) == 0
    rows = list(csv.DictReader((tmp_path / "map.csv").open()))
    assert [(float(r["control.k_xi"]), float(r["dcm.b"])) for r in rows] == [
        (2.0, 0.28),
        (2.0, 0.3),
        (6.0, 0.28),
        (6.0, 0.3),
    ]
    assert {r["controller"] for r in rows} == {"preset"}
    assert (tmp_path / "map.png").stat().st_size > 10_000
    result = json.loads((tmp_path / "map.json").read_text())
    assert result["preset_point"] == [3.0, 0.3]
    # one corner recomputed as a plain envelope of the preset with those values
    base = load_preset(WALK)
    corner = base.replace(control={"k_xi": 6.0}, dcm={"b": 0.28})
    settings = SweepSettings(
        backend="lip", directions=2, grid=3, iterations=2, jobs=1, controllers=("preset",)
    )
    env = envelope(corner, settings)
    assert float(rows[2]["weakest_ns"]) == pytest.approx(envelope_metric(env["rows"], "weakest"))
    assert float(rows[2]["mean_ns"]) == pytest.approx(envelope_metric(env["rows"], "mean"))

    # --resume: every rollout comes from rollouts.jsonl, same map
    capsys.readouterr()
    before = (tmp_path / "map.csv").read_text()
    assert main([*args, *grid, "--resume"]) == 0
    assert "0 rollouts run" in capsys.readouterr().out
    assert (tmp_path / "map.csv").read_text() == before


def test_envelope_metrics_against_hand_values() -> None:
    rows = [
        {"direction_deg": d, "controller": "c", "max_impulse_ns": j}
        for d, j in ((0.0, 2.0), (90.0, 1.0), (180.0, 2.0), (270.0, 1.0))
    ]
    assert envelope_metric(rows, "weakest") == 1.0
    assert envelope_metric(rows, "mean") == 1.5
    assert envelope_metric(rows, "area") == pytest.approx(4.0)  # a rhombus of diagonals 4 and 2


@pytest.mark.parametrize(
    ("grid", "needle"),
    [
        (["control.k_xi"], "start:stop:count"),
        (["control.nope=1:2:3"], "control.nope"),
        (["control.observer=0:1:2"], "control.observer"),
        (["dcm.b=0.2:0.4:3"], "dcm.b"),
        (["control.k_xi=1:2:0"], "count"),
        (["control.k_xi=1:2:2", "dcm.b=0.28:0.3:2", "gait.t_ss=0.6:0.7:2"], "two keys"),
    ],
)
def test_bad_grid_exits_2(capsys, tmp_path: Path, grid, needle) -> None:
    assert main([str(WALK), *COARSE, "--out", str(tmp_path), "--grid", *grid]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err
