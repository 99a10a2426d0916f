"""The dashboard's Sweep panel, driven through its callbacks (no browser): a tiny envelope run
in the background on a one-CPU Ray instance gives the serial ``envelope(...)`` numbers; a
cancelled sweep stops and keeps the panel usable; exports are the report's files."""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Iterator

import pytest

viser = pytest.importorskip("viser")
pytest.importorskip("ray")

from helpers import free_port  # noqa: E402

from dcmviz.config import Config  # noqa: E402
from dcmviz.dashboard.notify import Notifier  # noqa: E402
from dcmviz.dashboard.sweep_panel import SweepPanel  # noqa: E402
from dcmviz.sweep import SerialRunner, envelope  # noqa: E402

CONFIG = Config().replace(sim={"backend": "lip"})


@pytest.fixture
def server() -> Iterator[viser.ViserServer]:
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    yield server
    server.stop()


def tiny(panel: SweepPanel) -> None:
    panel.gui_backend.value = "point mass (lip)"
    panel.gui_directions.value = 2
    panel.gui_iterations.value = 2
    panel.gui_controllers.value = "tracking, step adjustment"


def test_panel_sweep_on_ray_equals_the_serial_envelope(server) -> None:
    panel = SweepPanel(server.gui, lambda: CONFIG, Notifier(server))
    tiny(panel)
    progress: list[float] = []
    assert panel.start()
    while not panel.wait(0.05):
        progress.append(float(panel.gui_progress.value))
    assert panel.state == "done", panel.gui_status.content
    settings = panel.settings()
    serial = envelope(CONFIG, settings)  # jobs = 1: serial, in this process, no Ray
    got = {(r["direction_deg"], r["controller"]): r for r in panel.result["rows"]}
    want = {(r["direction_deg"], r["controller"]): r for r in serial["rows"]}
    assert got.keys() == want.keys() and len(got) == 4
    for key, row in want.items():
        assert got[key]["max_impulse_ns"] == row["max_impulse_ns"], key
        assert got[key]["first_fail_impulse_ns"] == row["first_fail_impulse_ns"], key
    # rows arrived one finished cell at a time, with the same numbers
    assert sorted((r["direction_deg"], r["controller"], r["max_impulse_ns"]) for r in panel.rows) \
        == sorted((*k, r["max_impulse_ns"]) for k, r in want.items())  # fmt: skip
    assert panel.result["rollouts"]["runner"] == "ray"
    assert panel.gui_progress.value == 100.0 and progress == sorted(progress)
    assert panel.gui_plot.visible and panel.gui_plot.image.shape[2] == 3
    # exports: the report's JSON, CSV and PNG of that result
    exported = json.loads(panel.export("json", None))
    assert exported["rows"] == json.loads(json.dumps(panel.result["rows"]))
    rows = list(csv.DictReader(io.StringIO(panel.export("csv", None).decode())))
    assert len(rows) == 4
    assert panel.export("png", None)[:8] == b"\x89PNG\r\n\x1a\n"
    assert not panel.gui_start.disabled and panel.gui_cancel.disabled


def test_cancel_stops_the_sweep_and_the_panel_starts_again(server) -> None:
    notifier = Notifier(server)
    panel = SweepPanel(server.gui, lambda: CONFIG, notifier, runner_factory=SerialRunner)
    tiny(panel)
    panel.gui_directions.value = 8
    seen: list[int] = []
    original = panel._on_result

    def on_result(event, config, settings) -> None:  # cancel after the third answer
        seen.append(event.done)
        if len(seen) == 3:
            panel.cancel()
        original(event, config, settings)

    panel._on_result = on_result  # type: ignore[method-assign]
    assert panel.start()
    assert not panel.start()  # one sweep at a time
    assert panel.wait(60)
    assert panel.state == "cancelled" and len(seen) == 3  # no probe answered after it
    assert panel.result is None and panel.export("csv", None) is None
    assert not panel.gui_start.disabled
    panel._on_result = original  # type: ignore[method-assign]
    panel.gui_directions.value = 2
    assert panel.start() and panel.wait(60) and panel.state == "done"
