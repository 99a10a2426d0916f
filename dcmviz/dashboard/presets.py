"""The Presets folder: choose a preset file, upload one, export the current configuration."""

from __future__ import annotations

from pathlib import Path
from typing import Any

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


def _flat(data: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(data, dict):
        out: dict[str, Any] = {}
        for key, value in data.items():
            out.update(_flat(value, f"{prefix}.{key}" if prefix else key))
        return out
    return {prefix: data}


def _short(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, list | tuple):
        return f"[{len(value)} items]" if len(value) > 3 else str(value)
    return str(value)


def changes(base: Config, config: Config) -> list[str]:
    """What differs between two configs, one 'key old → new' per setting (name and
    description left out)."""
    a, b = _flat(base.to_dict()), _flat(config.to_dict())
    out = []
    for key in sorted(set(a) | set(b)):
        if key in ("name", "description") or a.get(key) == b.get(key):
            continue
        old, new = a.get(key), b.get(key)
        if isinstance(old, list) or isinstance(new, list):  # footsteps, pushes, terrain boxes
            n_old = len(old) if isinstance(old, list) else 0
            n_new = len(new) if isinstance(new, list) else 0
            out.append(f"{key} changed ({n_old} → {n_new} entries)")
            continue
        out.append(f"{key} {_short(a.get(key, '—'))} → {_short(b.get(key, '—'))}")
    return out


def export_defaults(base: Config, config: Config) -> tuple[str, str, str]:
    """(file name, name, description) an export of ``config`` offers when ``base`` is the
    preset it was loaded as: unchanged, the preset's own; edited, a name and a description
    that say what changed (the preset's would no longer match)."""
    changed = changes(base, config)
    if not changed:
        return slug(config.name) + ".toml", config.name, config.description
    name = base.name if base.name.endswith("(edited)") else f"{base.name} (edited)"
    description = f"Edited from “{base.name}”: {'; '.join(changed)}."
    return slug(name) + ".toml", name, description


def clean_file_name(text: str) -> str:
    """A safe ``*.toml`` file name from what a user typed (ValueError if nothing is left)."""
    stem = text.strip()
    if stem.lower().endswith(".toml"):
        stem = stem[:-5]
    stem = "".join(c if c.isalnum() or c in "-_." else "_" for c in stem).strip("._")[:100]
    if not stem:
        raise ValueError(f"file name {text!r}: use letters, digits, '-', '_' (e.g. my_walk.toml)")
    return stem + ".toml"


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
            self.gui_export = gui.add_button(
                "Export preset…", icon=viser.Icon.DOWNLOAD,
                hint="Asks for a file name and a description (suggested from what you changed)",
            )  # fmt: skip
            self.gui_export.on_click(
                notifier.guarded("Export preset", lambda event: self.on_export(event.client))
            )
            self.gui_description = gui.add_markdown("")
        self.base = editor.config  # the preset loaded last: exports say what changed since
        self.exports = 0
        self.show(editor.config, self.gui_preset.value)
        editor.on_applied(self.show)

    def preset_names(self) -> list[str]:
        return sorted(p.stem for p in self.presets_dir.glob("*.toml"))

    def show(self, config: Config, preset: str) -> None:
        """The adopted config's name and description; the dropdown names its preset file."""
        self.gui_preset.value = preset  # its callback ignores CURRENT
        if preset != CURRENT:
            self.base = config
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
            self.base = config  # exports say what changed since this file
            self.notifier.notify(client, "Preset loaded", f"{filename}: {config.name}")
        return ok

    def on_export(self, client: viser.ClientHandle | None) -> Any:
        """Ask the tab for a file name and a description (suggested: what changed since the
        preset was loaded), then send the preset (:meth:`export`)."""
        file_name, name, description = export_defaults(self.base, self.editor.config)
        if client is None:
            return self.export(None, file_name, name, description)
        changed = changes(self.base, self.editor.config)
        modal = client.gui.add_modal("Export preset")
        with modal:
            client.gui.add_markdown(
                f"<small>Changed since “{self.base.name}”: {'; '.join(changed)}</small>"
                if changed else f"<small>Unchanged since “{self.base.name}”.</small>"
            )  # fmt: skip
            gui_file = client.gui.add_text("file name", initial_value=file_name)
            gui_name = client.gui.add_text("name", initial_value=name)
            gui_description = client.gui.add_text(
                "description", initial_value=description, multiline=True
            )
            gui_download = client.gui.add_button("Download", icon=viser.Icon.DOWNLOAD)
            gui_cancel = client.gui.add_button("Cancel")

        def download(_event: Any) -> None:
            try:
                self.export(client, gui_file.value, gui_name.value, gui_description.value)
            except ValueError as err:
                self.notifier.notify(client, "Export refused", str(err), error=True)
                return
            modal.close()

        gui_download.on_click(self.notifier.guarded("Export preset", download))
        gui_cancel.on_click(lambda _event: modal.close())
        return modal

    def export(
        self, client: viser.ClientHandle | None, file_name: str, name: str, description: str
    ) -> bytes:
        """The current config named ``name`` with ``description``, as ``file_name`` (TOML), sent
        to the client as a download; ValueError for a file name or text that cannot be."""
        file_name = clean_file_name(file_name)
        name, description = name.strip(), description.strip()
        if not name:
            raise ValueError("name: give the preset a name")
        if len(name) > 200 or len(description) > 2000:
            raise ValueError("name ≤ 200 and description ≤ 2000 characters")
        config = self.editor.config.model_copy(update={"name": name, "description": description})
        text = dumps_preset(config).encode("utf-8")
        loads_preset(text.decode("utf-8"))  # what is sent loads back
        self.exports += 1
        if config != self.editor.config:  # the dashboard's config is named so from now on
            self.editor.apply_config(config, client)
        self.base = config
        if client is not None:
            client.send_file_download(file_name, text, save_immediately=True)
            self.notifier.notify(client, "Preset exported", f"{file_name}: “{name}”")
        return text
