"""The Recording folder: a rerun recording of the running session, offered for download."""

from __future__ import annotations

import shutil
import socket
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import viser

from dcmviz.dashboard.loop import SimLoop
from dcmviz.dashboard.notify import Notifier
from dcmviz.dashboard.presets import slug
from dcmviz.record import Recorder
from dcmviz.robots.heap import release_freed_memory


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class RecordingPanel:
    """Handles ``gui_record``, ``gui_live`` and ``gui_progress``: ticking Record starts a
    :class:`~dcmviz.record.Recorder` on the simulation thread (also served live to rerun viewers
    when ``gui_live`` is ticked), unticking stops it and sends the ``.rrd``; while it runs the
    panel shows its length and size."""

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
        self._started = 0.0
        self._shown = ""
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
            self.gui_live = gui.add_checkbox(
                "Live stream to a rerun viewer", initial_value=True,
                hint="While recording, serve it on 127.0.0.1 so `rerun rerun+http://…/proxy` "
                "shows it live (the address appears below)",
            )  # fmt: skip
            self.gui_progress = gui.add_markdown("<small>not recording</small>")

    def on_record(self, recording: bool, client: viser.ClientHandle | None) -> bytes | None:
        """Start a recording, or stop it and return (and send) the .rrd bytes."""
        return self.start(client) if recording else self.stop(client)

    def start(self, client: viser.ClientHandle | None) -> None:
        if self.recorder is not None:
            return None
        recorder = Recorder()
        path = Path(tempfile.mkdtemp(prefix="dcmviz-")) / (slug(self.name()) + ".rrd")
        recorder.on_tick = self._contained(recorder, path)  # the session subscribes this
        port = free_port() if self.gui_live.value else None
        try:
            self.loop.call(lambda session: recorder.start(session, path, serve_port=port))
        except Exception as err:  # noqa: BLE001 - tell the user, keep the session running
            self.notifier.notify(client, "Recording failed", str(err), error=True)
            shutil.rmtree(path.parent, ignore_errors=True)
            self.gui_record.value = False
            return None
        self.recorder = recorder if recorder.recording else None  # (it may have failed already)
        self._started = time.monotonic()
        self.refresh()
        return None

    def progress(self) -> str:
        """What the running recording holds: its length (simulated and wall), its file size,
        and where a rerun viewer connects to it live."""
        recorder = self.recorder
        if recorder is None or recorder.path is None:
            return "<small>not recording</small>"
        try:
            size = recorder.path.stat().st_size
        except OSError:
            size = 0
        text = (
            f"<small>● recording {time.monotonic() - self._started:.0f} s, "
            f"{recorder.samples * recorder.log_dt_s:.1f} s of walk, {size / 1e6:.1f} MB"
        )
        if recorder.url:
            text += f"; live: `rerun {recorder.url}`"
        return text + "</small>"

    def refresh(self) -> None:
        """Rewrite the progress line if it changed (the render thread calls it every second)."""
        text = self.progress()
        if text != self._shown:
            self._shown = text
            self.gui_progress.content = text

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
        self.refresh()
        return data
