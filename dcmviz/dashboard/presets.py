"""The Presets folder: choose a preset file, upload one, export the current configuration."""

from __future__ import annotations

from pathlib import Path

import viser

from dcmviz.config import (
    MAX_PRESET_BYTES,
    PRESETS_DOC,
    Config,
    ConfigError,
    dumps_preset,
    load_preset,
    loads_preset,
)
from dcmviz.dashboard.editor import CURRENT, ConfigEditor
from dcmviz.dashboard.notify import Notifier


def slug(name: str) -> str:
    """A file name stem for a preset or recording name."""
    text = "".join(c.lower() if c.isalnum() else "_" for c in name).strip("_")
    return text or "dcmviz_preset"


class PresetPanel:
    """Handles ``gui_preset``, ``gui_upload``, ``gui_export``, ``gui_description``."""

    def __init__(
        self,
        gui: viser.GuiApi,
        editor: ConfigEditor,
        notifier: Notifier,
        presets_dir: Path | str,
        initial: str = CURRENT,
    ) -> None:
        self.editor = editor
        self.notifier = notifier
        self.presets_dir = Path(presets_dir)
        with gui.add_folder("Presets"):
            names = (CURRENT, *self.preset_names())
            self.gui_preset = gui.add_dropdown(
                "preset", names, initial_value=initial if initial in names else CURRENT
            )
            self.gui_preset.on_update(
                notifier.guarded(
                    "preset",
                    lambda event: self.on_preset_selected(event.target.value, event.client),
                )
            )
            self.gui_upload = gui.add_upload_button(
                "Upload preset (.toml)", icon=viser.Icon.UPLOAD, mime_type=".toml,text/plain"
            )
            self.gui_upload.on_upload(
                notifier.guarded("Upload preset", lambda event: self.on_upload(
                    event.target.value.name, event.target.value.content, event.client
                ))
            )  # fmt: skip
            self.gui_export = gui.add_button("Export preset", icon=viser.Icon.DOWNLOAD)
            self.gui_export.on_click(
                notifier.guarded("Export preset", lambda event: self.on_export(event.client))
            )
            self.gui_description = gui.add_markdown("")
        self.show(editor.config, self.gui_preset.value)
        editor.on_applied(self.show)

    def preset_names(self) -> list[str]:
        return sorted(p.stem for p in self.presets_dir.glob("*.toml"))

    def show(self, config: Config, preset: str) -> None:
        """The adopted config's name and description; the dropdown names its preset file."""
        self.gui_preset.value = preset  # its callback ignores CURRENT
        self.gui_description.content = (
            f"**{config.name}**  \n{config.description}" if config.description else
            f"**{config.name}**"
        )  # fmt: skip

    # -- callbacks ------------------------------------------------------------------------------
    def on_preset_selected(self, name: str, client: viser.ClientHandle | None = None) -> bool:
        if name == CURRENT:
            return False
        try:
            config = load_preset(self.presets_dir / f"{name}.toml")
        except ConfigError as err:
            self.notifier.notify(
                client, "Preset not loaded", f"{err} (preset schema: {PRESETS_DOC})", error=True
            )
            self.gui_preset.value = CURRENT
            return False
        return self.editor.apply_config(config, client, preset=name)

    def on_upload(self, filename: str, content: bytes, client: viser.ClientHandle | None) -> bool:
        """An uploaded TOML preset: size-limited, validated, adopted or refused with a reason.

        (The guard already refused an upload whose declared size is too large or zero before
        viser stored any of it; this is the check of what arrived.)"""
        see = f" (preset schema: {PRESETS_DOC})"
        why = ""
        if not content.strip():
            why = "the file is empty; a preset needs at least its [gait] or [dcm] settings"
        elif len(content) > MAX_PRESET_BYTES:
            why = f"{len(content)} bytes; a preset is at most {MAX_PRESET_BYTES} bytes"
        if why:
            self.notifier.notify(client, "Preset refused", f"{filename}: {why}{see}", error=True)
            return False
        try:
            config = loads_preset(content.decode("utf-8"))
        except UnicodeDecodeError:
            self.notifier.notify(
                client, "Preset refused", f"{filename}: not UTF-8 text{see}", error=True
            )
            return False
        except ConfigError as err:
            text = str(err)
            if PRESETS_DOC not in text:
                text += see
            self.notifier.notify(client, "Preset refused", f"{filename}: {text}", error=True)
            return False
        ok = self.editor.apply_config(config, client)
        if ok:
            self.notifier.notify(client, "Preset loaded", f"{filename}: {config.name}")
        return ok

    def on_export(self, client: viser.ClientHandle | None) -> bytes:
        """The current config as TOML, sent to the client as a download."""
        config = self.editor.config
        text = dumps_preset(config).encode("utf-8")
        if client is not None:
            client.send_file_download(slug(config.name) + ".toml", text, save_immediately=True)
        return text
