"""The Sweep panel: a push-recovery envelope of the current configuration, in the background.

Start runs :func:`dcmviz.sweep.envelope` in a thread of its own on a Ray instance with one CPU
(the rollouts run in a Ray worker process, so the live simulation keeps its core), shows the
probes answered on a progress bar, redraws the polar plot (the sweep report's, as an image) each
time a (direction, controller) cell finishes, and can be cancelled (the callback raises, the
sweep stops, the finished cells stay shown).  A finished sweep exports as JSON, CSV and PNG (the
files of :func:`dcmviz.sweep.write_envelope`) to the tab that asks.
"""

from __future__ import annotations

import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import viser

from dcmviz.config import Config
from dcmviz.dashboard.notify import Notifier

BACKENDS = {"point mass (lip)": "lip", "humanoid (mujoco)": "mujoco"}
CONTROLLER_SETS = {
    "tracking, step adjustment": ("tracking", "step_adjustment"),
    "all three": ("tracking", "step_adjustment", "step_adjustment+observer"),
    "the preset's own": ("preset",),
}
EXPORTS = ("json", "csv", "png")
PLOT_PX = 480  # the polar plot image is this many pixels square

RunnerFactory = Callable[[], Any]  # () -> a dcmviz.sweep runner (submit/next/close)


class SweepCancelled(Exception):
    """Raised from the sweep's callback to stop it (the sweep keeps finished rollouts)."""


def ray_runner() -> Any:
    """One CPU of a local Ray instance: the rollouts never take the simulation's core."""
    from dcmviz.sweep import RayRunner

    return RayRunner(num_cpus=1)


def partial_result(config: Config, settings: Any, rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The fields of an envelope result that the report's polar plot reads, for the cells that
    finished so far (the plot of a finished sweep uses the sweep's own result)."""
    from dcmviz.sweep.experiments import envelope_header, envelope_window

    window = envelope_window(config.replace(pushes=[]), settings)
    return {**envelope_header(config, settings, window), "rows": rows}


def polar_png(result: dict[str, Any], path: Path) -> np.ndarray:
    """Draw the report's polar plot to ``path`` and return it as an RGB image array."""
    import matplotlib.image

    from dcmviz.sweep import plot_polar

    rows = result["rows"]
    shown = {**result, "settings": {**result["settings"]}}
    shown["settings"]["controllers"] = [
        c for c in result["settings"]["controllers"] if any(r["controller"] == c for r in rows)
    ]
    plot_polar(shown, path, compact=True)
    image = matplotlib.image.imread(path)
    rgb = image[..., :3]
    return (rgb * 255).astype(np.uint8) if rgb.dtype != np.uint8 else rgb


class SweepPanel:
    """Handles ``gui_backend``, ``gui_directions``, ``gui_iterations``, ``gui_controllers``,
    ``gui_start``, ``gui_cancel``, ``gui_progress``, ``gui_plot`` and the export buttons."""

    def __init__(
        self,
        gui: viser.GuiApi,
        config: Callable[[], Config],
        notifier: Notifier,
        *,
        runner_factory: RunnerFactory = ray_runner,
    ) -> None:
        self.config = config  # the configuration a sweep starts from (the editor's)
        self.notifier = notifier
        self.runner_factory = runner_factory
        self.result: dict[str, Any] | None = None  # the last finished envelope
        self.rows: list[dict[str, Any]] = []  # cells finished so far (the running sweep)
        self.state = "idle"  # idle | running | cancelling | done | cancelled | failed
        self.done = threading.Event()  # set when a sweep thread ends
        self._cancel = threading.Event()
        self._thread: threading.Thread | None = None
        self._dir = Path(tempfile.mkdtemp(prefix="dcmviz-sweep-"))
        self._files: dict[str, bytes] = {}
        with gui.add_folder("Push-recovery envelope"):
            gui.add_markdown(
                "<small>The largest push impulse the walk survives, per direction and "
                "controller (`python -m dcmviz.sweep`), run in the background on one CPU.</small>"
            )
            self.gui_backend = gui.add_dropdown(
                "model", tuple(BACKENDS), initial_value="point mass (lip)"
            )
            self.gui_directions = gui.add_slider(
                "directions", min=2, max=16, step=1, initial_value=4
            )
            self.gui_iterations = gui.add_slider(
                "bisections", min=1, max=7, step=1, initial_value=3,
                hint="bisection steps after the coarse grid (resolution halves with each)",
            )  # fmt: skip
            self.gui_controllers = gui.add_dropdown(
                "controllers", tuple(CONTROLLER_SETS), initial_value="tracking, step adjustment"
            )
            self.gui_start = gui.add_button("Start sweep", icon=viser.Icon.PLAYER_PLAY)
            self.gui_cancel = gui.add_button("Cancel", icon=viser.Icon.X, disabled=True)
            self.gui_progress = gui.add_progress_bar(0.0)
            self.gui_status = gui.add_markdown("<small>no sweep yet</small>")
            self.gui_plot = gui.add_image(
                np.full((8, 8, 3), 255, np.uint8), label="envelope (N·s)", visible=False
            )
            self.gui_export = {
                kind: gui.add_button(f"Export {kind.upper()}", icon=viser.Icon.DOWNLOAD,
                                     disabled=True)
                for kind in EXPORTS
            }  # fmt: skip
        self.gui_start.on_click(notifier.guarded("Start sweep", lambda e: self.start(e.client)))
        self.gui_cancel.on_click(notifier.guarded("Cancel sweep", lambda e: self.cancel()))
        for kind, button in self.gui_export.items():
            button.on_click(
                notifier.guarded("Export sweep", lambda e, k=kind: self.export(k, e.client))
            )

    # -- what the controls ask for ---------------------------------------------------------
    def settings(self) -> Any:
        """The sweep settings of the panel (coarse: 4 grid points, few bisections)."""
        from dcmviz.sweep import SweepSettings

        return SweepSettings(
            backend=BACKENDS[self.gui_backend.value],
            directions=int(self.gui_directions.value),
            iterations=int(self.gui_iterations.value),
            grid=4,
            controllers=CONTROLLER_SETS[self.gui_controllers.value],
            jobs=1,
        )

    # -- callbacks -------------------------------------------------------------------------
    def start(self, client: viser.ClientHandle | None = None) -> bool:
        """Start a sweep of the current configuration unless one runs."""
        if self._thread is not None and self._thread.is_alive():
            self.notifier.notify(client, "Sweep", "a sweep is running; cancel it first")
            return False
        config, settings = self.config(), self.settings()
        self._cancel.clear()
        self.done.clear()
        self.rows, self.result, self._files = [], None, {}
        for button in self.gui_export.values():
            button.disabled = True
        self.gui_start.disabled, self.gui_cancel.disabled = True, False
        self.gui_progress.value = 0.0
        self.gui_progress.animated = True
        self._set_state("running", "starting the workers…")
        self._thread = threading.Thread(
            target=self._run, args=(config, settings), name="dcmviz-sweep", daemon=True
        )
        self._thread.start()
        return True

    def cancel(self) -> None:
        """Stop the running sweep at its next answered probe."""
        if self._thread is not None and self._thread.is_alive():
            self._cancel.set()
            self._set_state("cancelling", "cancelling…")

    def export(self, kind: str, client: viser.ClientHandle | None) -> bytes | None:
        """The finished sweep's envelope.``kind`` to the tab that asked (and returned)."""
        data = self._files.get(kind)
        if data is None:
            self.notifier.notify(client, "Sweep", "no finished sweep to export", error=True)
            return None
        if client is not None:  # saved at once: no notice left to close per export
            client.send_file_download(f"envelope.{kind}", data, save_immediately=True)
        return data

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the running sweep ends (tests)."""
        return self.done.wait(timeout)

    # -- the sweep thread ------------------------------------------------------------------
    def _run(self, config: Config, settings: Any) -> None:
        from dcmviz.sweep import Execution, envelope, write_envelope

        t0 = time.perf_counter()
        runner = None
        try:
            runner = self.runner_factory()
            result = envelope(
                config,
                settings,
                Execution(runner=runner, on_result=lambda e: self._on_result(e, config, settings)),
            )
            out = self._dir / "export"
            paths = write_envelope(result, out)
            self._files = {p.suffix[1:]: p.read_bytes() for p in paths}
            self.result = result
            self._draw(result)
            for button in self.gui_export.values():
                button.disabled = False
            self.gui_progress.value = 100.0
            self._set_state(
                "done", f"done: {result['rollouts']['run']} rollouts in "
                f"{time.perf_counter() - t0:.0f} s; weakest {weakest(result)}",
            )  # fmt: skip
        except SweepCancelled:
            self._set_state("cancelled", f"cancelled; {len(self.rows)} cells finished")
        except Exception as err:  # noqa: BLE001 - tell the user, keep the dashboard running
            self._set_state("failed", f"failed: {err}")
            self.notifier.notify(None, "Sweep failed", str(err), error=True)
        finally:
            if runner is not None:
                try:
                    runner.close()
                except Exception:  # noqa: BLE001 - closing a Ray instance that is gone
                    pass
            self.gui_progress.animated = False
            self.gui_start.disabled, self.gui_cancel.disabled = False, True
            self.done.set()

    def _on_result(self, event: Any, config: Config, settings: Any) -> None:
        """Each answered probe: progress; each finished cell: a row and a new polar plot."""
        if self._cancel.is_set():
            raise SweepCancelled
        self.gui_progress.value = round(100.0 * event.done / max(event.total, 1), 1)
        if event.boundary is None:
            return
        b = event.boundary
        self.rows.append(
            {**event.cell.label, "max_impulse_ns": b.max_ok, "capped": b.capped, "runs": b.runs}
        )
        self._set_state(
            "running", f"{len(self.rows)} cells finished, {event.done} of ≤ {event.total} probes"
        )
        self._draw(partial_result(config, settings, list(self.rows)))

    def _draw(self, result: dict[str, Any]) -> None:
        self.gui_plot.image = polar_png(result, self._dir / "live.png")
        self.gui_plot.visible = True

    def _set_state(self, state: str, text: str) -> None:
        self.state = state
        self.gui_status.content = f"<small>{text}</small>"


def weakest(result: dict[str, Any]) -> str:
    """The weakest direction of the best controller, e.g. '38.4 N·s at 270° (step_adjustment)'."""
    best = max(
        result["settings"]["controllers"],
        key=lambda c: min(r["max_impulse_ns"] for r in result["rows"] if r["controller"] == c),
    )
    row = min((r for r in result["rows"] if r["controller"] == best),
              key=lambda r: r["max_impulse_ns"])  # fmt: skip
    return f"{row['max_impulse_ns']:.1f} N·s at {row['direction_deg']:g}° ({best})"
