"""The Recording folder: a rerun recording of the running session, offered for download."""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import viser

from dcmviz.dashboard.loop import SimLoop
from dcmviz.dashboard.notify import Notifier
from dcmviz.dashboard.presets import slug
from dcmviz.record import Recorder
from dcmviz.robots.heap import release_freed_memory


class RecordingPanel:
    """Handle ``gui_record``: ticking starts a :class:`~dcmviz.record.Recorder` on the simulation
    thread, unticking stops it and sends the ``.rrd``."""

    def __init__(
        self,
        gui: viser.GuiApi,
        loop: SimLoop,
        notifier: Notifier,
        name: Callable[[], str],
    ) -> None:
        self.loop = loop
        self.notifier = notifier
        self.name = name  # the current preset's name, for the file name
        self.recorder: Recorder | None = None
        self.failures = 0  # recordings stopped by an exception in the recorder
        with gui.add_folder("Recording"):
            self.gui_record = gui.add_checkbox(
                "Record (rerun)", initial_value=False,
                hint="Capture a rerun recording; unticking offers the .rrd for download",
            )  # fmt: skip
            self.gui_record.on_update(
                notifier.guarded(
                    "Record", lambda event: self.on_record(event.target.value, event.client)
                )
            )

    def on_record(self, recording: bool, client: viser.ClientHandle | None) -> bytes | None:
        """Start a recording, or stop it and return (and send) the .rrd bytes."""
        return self.start(client) if recording else self.stop(client)

    def start(self, client: viser.ClientHandle | None) -> None:
        if self.recorder is not None:
            return None
        recorder = Recorder()
        path = Path(tempfile.mkdtemp(prefix="dcmviz-")) / (slug(self.name()) + ".rrd")
        recorder.on_tick = self._contained(recorder, path)  # the session subscribes this
        try:
            self.loop.call(lambda session: recorder.start(session, path))
        except Exception as err:  # noqa: BLE001 - tell the user, keep the session running
            self.notifier.notify(client, "Recording failed", str(err), error=True)
            shutil.rmtree(path.parent, ignore_errors=True)
            self.gui_record.value = False
            return None
        self.recorder = recorder if recorder.recording else None  # (it may have failed already)
        return None

    def _contained(self, recorder: Recorder, path: Path) -> Callable[[Any], None]:
        """The recorder's per-tick logging; an exception in it ends the recording (told to
        everyone), never the walk: the session would otherwise raise it from every tick."""
        log = recorder.on_tick
        failed: list[Exception] = []

        def on_tick(tick: Any) -> None:
            if failed:
                return
            try:
                log(tick)
            except Exception as err:  # noqa: BLE001 - the recorder, not the simulation, failed
                failed.append(err)
                self.failures += 1
                unsubscribe = getattr(recorder, "_unsubscribe", None)
                if unsubscribe is not None:
                    unsubscribe()  # on the simulation thread, between two ticks
                if self.recorder is recorder:
                    self.recorder = None
                try:
                    if recorder.stream is not None:
                        recorder.stream.disconnect()
                    recorder.stream = None
                except Exception:  # noqa: BLE001
                    pass
                shutil.rmtree(path.parent, ignore_errors=True)
                self.notifier.notify(
                    None, "Recording failed",
                    f"the recorder raised {err!r}; recording stopped, the walk continues",
                    error=True,
                )  # fmt: skip
                self.gui_record.value = False  # runs on_record(False): nothing left to stop

        return on_tick

    def stop(self, client: viser.ClientHandle | None) -> bytes | None:
        recorder, self.recorder = self.recorder, None
        if recorder is None:
            return None
        path = Path(self.loop.call(lambda session: recorder.stop()))
        data = path.read_bytes()
        shutil.rmtree(path.parent, ignore_errors=True)
        if client is not None:
            client.send_file_download(path.name, data, save_immediately=True)
        self.notifier.notify(client, "Recording ready", f"{path.name}: {recorder.samples} samples")
        release_freed_memory()  # the recorder's buffers (the .rrd is several MB)
        return data
