"""Dashboard callbacks → state, without a browser (the callbacks are called directly)."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

viser = pytest.importorskip("viser")

from dcmviz.config import (  # noqa: E402
    MAX_PRESET_BYTES,
    Config,
    dumps_preset,
    load_preset,
    loads_preset,
)
from dcmviz.dashboard import Dashboard  # noqa: E402
from dcmviz.dashboard.gui import label, slider_range  # noqa: E402
from dcmviz.dashboard.preview import preview_data  # noqa: E402
from dcmviz.gait import plan_from_config  # noqa: E402
from dcmviz.robots import get_spec  # noqa: E402

PRESETS = Path(__file__).resolve().parents[1] / "presets"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def dash() -> Iterator[Dashboard]:
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    config = Config().replace(sim={"backend": "lip"})
    d = Dashboard(server, config, presets_dir=PRESETS, start=False)
    assert d.preview.wait(0)
    yield d
    d.stop()
    server.stop()


def drain(d: Dashboard) -> None:
    """Apply the commands the callbacks posted to the (not running) simulation loop."""
    d.loop._handle_commands()


def test_slider_ranges_follow_the_schema() -> None:
    assert slider_range_of("gait", "t_ss") == (0.15, 3.0)  # gt 0.1 → one step in
    assert slider_range_of("dcm", "b") == (0.15, 0.6)
    assert label("gait", "t_ss") == "T_ss [s]"
    assert label("control", "k_xi") == "k_ξ [1/s]"


def slider_range_of(section: str, name: str) -> tuple[float, float]:
    from dcmviz.dashboard.gui import CONTROL_SLIDERS, DCM_SLIDERS, FOOTSTEP_SLIDERS

    spec = next(
        s
        for s in FOOTSTEP_SLIDERS + DCM_SLIDERS + CONTROL_SLIDERS
        if (s.section, s.name) == (section, name)
    )
    return slider_range(spec)


def test_field_change_rebuilds_preview_and_session(dash: Dashboard) -> None:
    assert dash.on_field_change("gait", "n_steps", 12.0)
    assert dash.config.gait.n_steps == 12
    assert dash.preview.wait(dash.version)
    assert len([s for s in dash.preview.data.soles if s.index >= 0]) == 12
    drain(dash)
    assert dash.loop.session.config == dash.config
    assert len(dash.loop.session.plan.steps) == 12
    # the preview is the plan's closed form, sampled: its end is the plan's last VRP waypoint
    plan = plan_from_config(dash.config)
    np.testing.assert_allclose(dash.preview.data.vrp[-1], plan.preview.waypoints[-1], atol=1e-9)


def test_order_dropdown_and_b_show_dz(dash: Dashboard) -> None:
    assert dash.on_field_change("dcm", "order", "3")
    assert dash.config.dcm.order == 3
    assert dash.on_field_change("dcm", "b", 0.32)
    assert "0.32" in dash.controls.extra["dz_vrp"].content
    assert f"{9.81 * 0.32**2:.3f}" in dash.controls.extra["dz_vrp"].content


def test_bad_value_is_refused_and_control_reverts(dash: Dashboard) -> None:
    before = dash.config
    version = dash.version
    handle = dash.controls.handles[("gait", "step_width")]
    handle.value = 0.06  # what the browser would send (the callback is suppressed here)
    assert not dash.on_field_change("gait", "step_width", 0.06)  # feet collide (min 0.14 m)
    assert dash.config is before and dash.version == version
    assert handle.value == pytest.approx(before.gait.step_width)
    title, body = dash.notifications[-1]
    assert title == "Invalid value" and "step_width" in body and "0.06" in body


def test_out_of_schema_value_is_refused(dash: Dashboard) -> None:
    before = dash.config
    assert not dash.on_field_change("gait", "t_ss", -0.7)
    assert dash.config is before
    assert "t_ss" in dash.notifications[-1][1]


def test_dragging_a_footstep_makes_footsteps_explicit(dash: Dashboard) -> None:
    plan = plan_from_config(dash.config)
    target = plan.steps[3].position + [0.05, 0.03, 0.0]
    assert dash.on_footstep_moved(3, target)
    steps = dash.config.gait.footsteps
    assert steps is not None and len(steps) == len(plan.steps)
    np.testing.assert_allclose(steps[3].position, target)
    new_plan = plan_from_config(dash.config)
    np.testing.assert_allclose(new_plan.steps[3].position, target)
    np.testing.assert_allclose(new_plan.steps[2].position, plan.steps[2].position)
    # across the stance foot: refused, explicit footsteps unchanged
    crossing = plan.steps[4].position.copy()
    crossing[1] = -crossing[1]
    assert not dash.on_footstep_moved(4, crossing)
    np.testing.assert_allclose(dash.config.gait.footsteps[4].position, plan.steps[4].position)
    # a geometric slider regenerates the footsteps
    assert dash.on_field_change("gait", "step_length", 0.25)
    assert dash.config.gait.footsteps is None


def test_presets_dropdown_upload_and_export(dash: Dashboard) -> None:
    assert "lateral_push" in dash.preset_names()
    assert dash.on_preset_selected("lateral_push")
    assert dash.config == load_preset(PRESETS / "lateral_push.toml")
    assert dash.controls.handles[("gait", "t_ss")].value == dash.config.gait.t_ss

    text = dumps_preset(Config().replace(gait={"n_steps": 4}, sim={"backend": "lip"}))
    assert dash.on_upload("mine.toml", text.encode(), None)
    assert dash.config.gait.n_steps == 4

    before = dash.config
    assert not dash.on_upload("big.toml", b"#" * (MAX_PRESET_BYTES + 1), None)
    assert not dash.on_upload("bad.toml", b"[gait]\nt_ss = -1.0\n", None)
    assert not dash.on_upload("junk.toml", b"\xff\xfe not text", None)
    assert dash.config is before
    assert "t_ss" in dash.notifications[-2][1]

    exported = dash.on_export(None)
    assert loads_preset(exported.decode()) == dash.config


def test_push_is_validated_and_posted(dash: Dashboard) -> None:
    dash.gui_push_direction.value = 90.0
    dash.gui_push_magnitude.value = 100.0
    assert dash.on_push()
    drain(dash)
    push = dash.loop.session.pushes[-1]
    np.testing.assert_allclose(push.force, [0.0, 100.0, 0.0], atol=1e-9)
    assert push.body == dash.gui_push_body.value
    dash.gui_push_ramp.value = 1.0  # longer than the push: refused
    assert not dash.push((1.0, 0.0, 0.0), 50.0, "torso", None)
    assert "ramp" in dash.notifications[-1][1]
    assert not dash.push((1.0, 0.0, 0.0), 50.0, "elbow", None)


def test_push_raises_and_recovers_dcm_error(dash: Dashboard) -> None:
    loop = dash.loop
    session = loop.session
    for _ in range(int(2.0 / session.backend.control_dt)):
        session.step()
    dash.gui_push_duration.value = 0.2
    assert dash.push((0.0, 1.0, 0.0), 80.0, "torso", None)
    drain(dash)
    errors = []
    for _ in range(int(3.0 / session.backend.control_dt)):
        cmd = session.step()
        errors.append(float(np.linalg.norm(cmd.xi - cmd.xi_ref)))
    assert max(errors) > 0.01
    assert errors[-1] < 0.3 * max(errors)
    assert not session.fell


def test_fall_notifies_and_resets() -> None:
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    config = Config().replace(sim={"backend": "lip"}, control={"step_adjustment": False})
    d = Dashboard(server, config, presets_dir=PRESETS, start=False)
    try:
        d.loop.start()
        time.sleep(0.3)
        assert d.push((1.0, 0.0, 0.0), 1000.0, "torso", None)
        deadline = time.time() + 10.0
        while d.loop.falls == 0 and time.time() < deadline:
            time.sleep(0.05)
        assert d.loop.falls == 1
        assert d.notifications[-1][0] == "Fall"
        while d.loop.session.fell and time.time() < deadline:
            time.sleep(0.05)
        assert not d.loop.session.fell  # reset after the pause, still running
        assert d.loop._thread.is_alive()
    finally:
        d.stop()
        server.stop()


def test_record_returns_rerun_bytes(dash: Dashboard) -> None:
    assert dash.on_record(True, None) is None
    assert len(dash.loop.session.subscribers) == 1
    for _ in range(50):
        dash.loop.session.step()
    data = dash.on_record(False, None)
    assert data is not None and len(data) > 1000 and data[:4] == b"RRF2"
    assert dash.loop.session.subscribers == ()
    assert dash.notifications[-1][0] == "Recording ready"


def test_preview_data_matches_plan() -> None:
    config = Config().replace(gait={"n_steps": 20})
    plan = plan_from_config(config)
    data = preview_data(plan, get_spec("talos"))
    # continuous VRP and DCM, sampled at phase boundaries too
    assert np.all(np.diff(data.t) >= 0)
    np.testing.assert_allclose(data.dcm[0], plan.preview.dcm(0.0))
    assert len(data.soles) == 22
    pts, colors = data.vrp_segments()
    assert pts.shape == (len(data.t) - 1, 2, 3) and colors.shape == pts.shape


def test_clicking_the_robot_pushes_along_the_view(dash: Dashboard) -> None:
    from types import SimpleNamespace

    dash.gui_push_magnitude.value = 60.0
    event = SimpleNamespace(ray_direction=(0.6, 0.0, -0.8), client=None)  # looking down, +x
    assert dash.on_body_click("pelvis", event)
    drain(dash)
    push = dash.loop.session.pushes[-1]
    np.testing.assert_allclose(push.force, [60.0, 0.0, 0.0], atol=1e-9)  # horizontal part only
    assert push.body == "pelvis"


def test_dragged_slider_configs_coalesce(dash: Dashboard) -> None:
    resets = []
    session = dash.loop.session
    original = session.set_config
    session.set_config = lambda *a, **k: (resets.append(a[0]), original(*a, **k))[1]
    for value in (0.21, 0.22, 0.23, 0.24):
        assert dash.on_field_change("gait", "step_length", value)
    drain(dash)
    assert len(resets) == 1 and resets[0].gait.step_length == 0.24
    assert dash.loop.version == dash.version


def test_mode_robot_and_backend_switch(dash: Dashboard) -> None:
    assert dash.on_field_change("gait", "mode", "continuous")
    drain(dash)
    session = dash.loop.session
    for _ in range(int(4.0 / session.backend.control_dt)):
        session.step()
    assert session.steps_completed >= 2 and not session.fell
    assert dash.on_field_change("robot", "model", "g1")
    drain(dash)
    assert dash.loop.session.config.robot.model == "g1"
    assert dash.gui_push_body.options == tuple(get_spec("g1").bodies)
    dash.loop._publish()
    assert dash.loop.snapshot.robot == "g1" and dash.loop.snapshot.backend == "lip"


def test_play_pause_reset_speed(dash: Dashboard) -> None:
    dash.on_play(False)
    assert dash.gui_play.label == "Play"
    dash.on_speed(0.5)
    dash.on_reset()
    drain(dash)
    assert not dash.loop.playing and dash.loop.speed == 0.5 and dash.loop.resets == 1
    dash.on_play(True)
    assert dash.gui_play.label == "Pause"


def test_preset_dropdown_follows_edits(dash: Dashboard) -> None:
    dash.gui_preset.value = "lateral_push"  # as the browser would: runs the callback
    assert dash.config.name == load_preset(PRESETS / "lateral_push.toml").name
    assert dash.gui_preset.value == "lateral_push"
    assert dash.on_field_change("control", "k_xi", 4.0)
    assert dash.gui_preset.value == "(current)"  # edited: no longer the preset file
    assert dash.config.control.k_xi == 4.0


def test_app_rejects_a_bad_preset_with_one_line(tmp_path: Path) -> None:
    import subprocess
    import sys

    bad = tmp_path / "bad.toml"
    bad.write_text("[gait]\nt_ss = -1.0\n")
    app = Path(__file__).resolve().parents[1] / "app.py"
    for arg in (str(bad), str(tmp_path / "missing.toml")):
        out = subprocess.run(
            [sys.executable, str(app), "--preset", arg], capture_output=True, text=True, timeout=60
        )
        assert out.returncode == 2
        assert len(out.stderr.strip().splitlines()) == 1 and "app.py:" in out.stderr


def test_app_serves_on_loopback() -> None:
    import subprocess
    import sys
    import urllib.request

    app = Path(__file__).resolve().parents[1] / "app.py"
    port = free_port()
    proc = subprocess.Popen(
        [sys.executable, str(app), "--port", str(port)],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        line = ""
        deadline = time.time() + 60
        while "dcmviz dashboard:" not in line and time.time() < deadline:
            line = proc.stdout.readline()
        assert f"http://localhost:{port}" in line
        assert urllib.request.urlopen(f"http://127.0.0.1:{port}", timeout=10).status == 200
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def test_export_with_dragged_footsteps_loads_back(dash: Dashboard) -> None:
    plan = plan_from_config(dash.config)
    assert dash.on_footstep_moved(1, plan.steps[1].position + [0.04, -0.02, 0.0])
    assert dash.on_field_change("dcm", "order", "3")
    config = loads_preset(dash.on_export(None).decode())
    assert config == dash.config and config.gait.footsteps is not None
