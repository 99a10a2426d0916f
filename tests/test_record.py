"""Rerun recorder: an .rrd is written, loads back, and holds the logged series and scene."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import rerun.chunk

from dcmviz.config import load_preset
from dcmviz.record import Recorder, record_session, urdf_visuals
from dcmviz.run import main
from dcmviz.session import Session

ROOT = Path(__file__).resolve().parents[1]


def rows_by_entity(path: Path) -> Counter:
    """Temporal rows per entity path, read back with rerun's own reader."""
    rows: Counter = Counter()
    for chunk in rerun.chunk.RrdReader(str(path)).store().stream():
        if not chunk.is_static:
            rows[str(chunk.entity_path)] += chunk.num_rows
    return rows


def test_lip_recording_loads_back(tmp_path: Path) -> None:
    config = load_preset(ROOT / "presets" / "lateral_push.toml")
    seen: list[float] = []
    session = Session(config, backend="lip", on_tick=lambda s: seen.append(s.t))
    path = record_session(session, tmp_path / "walk.rrd", 4.0)
    assert len(session.subscribers) == 1 and len(seen) == 800  # the earlier subscriber still ran
    assert path.stat().st_size > 50_000
    rows = rows_by_entity(path)
    samples = 400  # 4 s at 10 ms
    for entity in ("/plots/x", "/plots/y", "/plots/dcm_error", "/plots/force", "/world/points"):
        assert rows[entity] == pytest.approx(samples, abs=1), entity
    assert rows["/world/forces"] == rows["/world/points"]
    assert rows["/world/footsteps/realised"] >= 2  # a box set per touchdown
    assert rows["/world/footsteps/adjusted"] >= 1  # the push at 3 s adjusts a footstep
    assert rows["/world/robot/legs"] == rows["/world/points"]


def test_start_stop_restores_callback_and_streams_are_separate(tmp_path: Path) -> None:
    config = load_preset(ROOT / "presets" / "walk_forward.toml")
    a, b = Session(config, backend="lip"), Session(config, backend="lip")
    rec_a, rec_b = Recorder(), Recorder(log_dt_s=0.05)
    rec_a.start(a, tmp_path / "a.rrd")
    rec_b.start(b, tmp_path / "b.rrd")
    assert rec_a.stream is not rec_b.stream
    a.run(1.0)
    b.run(1.0)
    assert rec_a.stop() == tmp_path / "a.rrd" and a.subscribers == ()
    assert rec_b.stop() == tmp_path / "b.rrd" and b.subscribers == ()
    assert rows_by_entity(tmp_path / "a.rrd")["/plots/x"] == pytest.approx(100, abs=1)
    assert rows_by_entity(tmp_path / "b.rrd")["/plots/x"] == pytest.approx(20, abs=1)
    with pytest.raises(RuntimeError):
        rec_a.stop()


def test_runner_rrd_with_mujoco_robot(tmp_path: Path) -> None:
    path = tmp_path / "talos.rrd"
    preset = str(ROOT / "presets" / "walk_forward.toml")
    assert main([preset, "--sim", "mujoco", "--duration", "0.5", "--rrd", str(path)]) == 0
    rows = rows_by_entity(path)
    links = [e for e in rows if e.startswith("/world/robot/") and "visual" not in e]
    assert "/world/robot/torso_2_link" in links and len(links) > 20
    assert rows["/world/robot/torso_2_link"] == pytest.approx(50, abs=1)
    assert path.stat().st_size > 1_000_000  # the Talos meshes are in the file


def test_urdf_visuals_resolve_package_paths() -> None:
    from dcmviz.sim.robots import robot_source, robots_dir

    root = robots_dir()
    visuals = urdf_visuals(str(Path(root) / robot_source("talos").urdf), root)
    assert len(visuals) > 30
    assert all(Path(v.mesh).is_file() for v in visuals)
    for v in visuals:
        assert np.allclose(v.rotation @ v.rotation.T, np.eye(3), atol=1e-9)
