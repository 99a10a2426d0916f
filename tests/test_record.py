"""Rerun recorder: an .rrd is written, loads back, and holds the logged series and scene."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest
import rerun.chunk

from dcmviz.config import load_preset
from dcmviz.record import Recorder, record_session
from dcmviz.robots import load_robot
from dcmviz.run import main
from dcmviz.session import Session

ROOT = Path(__file__).resolve().parents[1]


def static_columns(path: Path) -> dict[str, set[str]]:
    """Component columns logged as static data, per entity path."""
    out: dict[str, set[str]] = {}
    for chunk in rerun.chunk.RrdReader(str(path)).store().stream():
        if chunk.is_static:
            names = {f.name for f in chunk.to_record_batch().schema}
            out.setdefault(str(chunk.entity_path), set()).update(names)
    return out


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
    # static data shadows temporal data of the same component: only styles may be static
    static = static_columns(path)
    assert "Points3D:positions" not in static["/world/points"]
    assert "Arrows3D:vectors" not in static["/world/forces"]
    assert "LineStrips3D:strips" not in static["/world/robot/legs"]


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
    """The humanoid's meshes are the shared visual model's, each posed per sample."""
    path = tmp_path / "talos.rrd"
    preset = str(ROOT / "presets" / "walk_forward.toml")
    assert main([preset, "--sim", "mujoco", "--duration", "0.5", "--rrd", str(path)]) == 0
    rows = rows_by_entity(path)
    meshes = load_robot("talos").visual.meshes
    for mesh in meshes:
        entity = f"/world/robot/talos/{mesh.name}"
        assert rows[entity] == pytest.approx(50 + 1, abs=1), entity  # poses + the mesh itself
    assert not any(e.startswith("/world/robot/legs") for e in rows)  # no point-mass legs
    assert path.stat().st_size > 1_000_000  # the Talos meshes are in the file


def test_recorder_reads_only_ticks_spec_and_plan(tmp_path: Path) -> None:
    """Recorder.start and on_tick work on an object that offers just what the recorder may read."""
    from types import SimpleNamespace

    config = load_preset(ROOT / "presets" / "walk_forward.toml")
    session = Session(config, backend="mujoco")
    ticks = []
    session.subscribe(ticks.append)
    session.run(0.2)
    facade = SimpleNamespace(
        spec=session.spec,
        nominal_plan=session.nominal_plan,
        config=session.config,
        subscribe=lambda f: lambda: None,
    )
    recorder = Recorder()
    recorder.start(facade, tmp_path / "facade.rrd")
    for tick in ticks:
        recorder.on_tick(tick)
    recorder.stop()
    rows = rows_by_entity(tmp_path / "facade.rrd")
    assert rows["/world/points"] == pytest.approx(20, abs=1)
    assert rows[f"/world/robot/talos/{load_robot('talos').visual.meshes[0].name}"] >= 20
