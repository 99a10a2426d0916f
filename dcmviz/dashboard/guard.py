"""Validate every GUI value a browser sends before viser stores or broadcasts it.

viser 1.1 stores a client's ``GuiUpdateMessage`` on the shared handle, casts it with the handle's
Python type and re-broadcasts it to every tab *before* any application callback runs.  One hostile
or malformed message can therefore poison the shared state: ``n = 1e30`` on an integer slider
becomes a 100-bit ``int`` that msgpack cannot serialise, and from then on every connection, old
and new, is closed with code 1011.  Other property names (``sync_cb``, ``removed``, ``options``)
are written onto the handle unchecked as well.

:func:`install_guard` puts a filter in front of viser's own handler.  A message passes only if it
names a known input handle and changes nothing but its ``value``, and that value is of the
handle's kind: a finite number clamped to the slider's range and rounded to its step (integer
handles stay integers), a boolean for a checkbox, one of the options for a dropdown.  Anything
else is dropped and the sender is told which control and what is allowed.

viser has no public hook for incoming messages, so this module is the one place in dcmviz that
reaches into viser's internals (``ViserServer._websock_server``, ``GuiApi._handle_gui_updates``,
``GuiApi._gui_input_handle_from_uuid``); ``tests/test_guard.py`` sends hostile messages through a
real websocket and fails if a viser upgrade moves them.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable
from typing import Any

import viser
from viser import _messages  # the message class the handler is registered for

Notify = Callable[[int, str, str], None]  # (client id, title, body)


class Rejected(ValueError):
    """A GUI value a client sent is not allowed; the message names the control and the range."""


def _label(handle: Any) -> str:
    return str(getattr(handle, "label", "") or "control")


def clean_value(handle: Any, value: Any) -> Any:
    """The value ``handle`` may store for a client's ``value``, or :class:`Rejected`."""
    name = _label(handle)
    if isinstance(handle, viser.GuiButtonHandle):
        if value is not True:
            raise Rejected(f"{name}: a button only takes a click")
        return True
    if isinstance(handle, viser.GuiButtonGroupHandle):  # a click on one of its buttons
        options = tuple(handle.options)
        if not isinstance(value, str) or value not in options:
            raise Rejected(f"{name} = {value!r}: allowed {', '.join(options)}")
        return value
    if isinstance(handle, viser.GuiCheckboxHandle):
        if not isinstance(value, bool):
            raise Rejected(f"{name} = {value!r}: must be true or false")
        return value
    if isinstance(handle, viser.GuiDropdownHandle):
        options = tuple(handle.options)
        if not isinstance(value, str) or value not in options:
            raise Rejected(f"{name} = {value!r}: allowed {', '.join(options)}")
        return value
    if isinstance(handle, viser.GuiSliderHandle | viser.GuiNumberHandle):
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise Rejected(f"{name} = {value!r}: must be a number")
        x = float(value)
        if not math.isfinite(x):
            raise Rejected(f"{name} = {value!r}: must be a finite number")
        lo, hi = handle.min, handle.max
        if lo is not None:
            x = max(x, float(lo))
        if hi is not None:
            x = min(x, float(hi))
        if isinstance(handle.value, int):  # an integer control keeps integer values
            if abs(x - round(x)) > 1e-9:
                raise Rejected(f"{name} = {value!r}: must be a whole number from {lo} to {hi}")
            return int(round(x))
        return x
    if isinstance(handle, viser.GuiTextHandle):
        if not isinstance(value, str) or len(value) > 10_000:
            raise Rejected(f"{name}: must be text of at most 10000 characters")
        return value
    raise Rejected(f"{name}: this control does not take values from the browser")


def changed_in_meaning(sent: Any, stored: Any) -> bool:
    """The stored value is not what the client meant: clamped into the range (beyond rounding)
    or another kind of value.  80 → 80.0 and a slider's 0.30000000000000004 → 0.3 are not."""
    if isinstance(stored, bool) or not isinstance(stored, numbers.Real):
        return sent != stored
    if isinstance(sent, bool) or not isinstance(sent, numbers.Real):
        return True
    return abs(float(sent) - float(stored)) > 1e-9 * max(1.0, abs(float(stored)))


def install_guard(
    server: viser.ViserServer,
    notify: Notify | None = None,
    *,
    max_upload_bytes: int | None = None,
    upload_doc: str = "",
) -> None:
    """Filter every incoming GUI update of ``server`` through :func:`clean_value`, and refuse an
    upload larger than ``max_upload_bytes`` (or empty) from the size its first message declares,
    before any of it is stored.

    ``notify(client_id, title, body)`` tells the sender why a value was refused or changed;
    ``upload_doc`` names the documentation an upload refusal points to.
    """
    gui = server.gui
    ws = server._websock_server
    original = gui._handle_gui_updates
    handles = gui._gui_input_handle_from_uuid

    async def guarded(client_id: int, message: Any) -> None:
        try:
            updates = message.updates
            handle = handles.get(message.uuid) if isinstance(message.uuid, str) else None
            if handle is None or not isinstance(updates, dict):
                return
            unknown = set(updates) - {"value"}
            if unknown or "value" not in updates:
                raise Rejected(
                    f"{_label(handle)}: only its value may be changed from the browser "
                    f"(got {', '.join(sorted(map(str, updates)))})"
                )
            value = clean_value(handle, updates["value"])
        except Rejected as err:
            if notify is not None:
                notify(client_id, "Value refused", str(err))
            return
        except Exception as err:  # noqa: BLE001 - a malformed message must never reach viser
            if notify is not None:
                notify(client_id, "Message refused", f"malformed GUI message: {err!r}"[:300])
            return
        changed = changed_in_meaning(updates["value"], value)
        updates_sent = updates["value"]
        message.updates = {"value": value}
        await original(client_id, message)
        if changed:  # the sender still shows what it typed: send everyone the stored value
            ws.queue_message(_messages.GuiUpdateMessage(message.uuid, {"value": value}))
            if notify is not None:
                lo, hi = getattr(handle, "min", None), getattr(handle, "max", None)
                allowed = f" (allowed {lo} to {hi})" if lo is not None and hi is not None else ""
                sent = updates_sent if isinstance(updates_sent, numbers.Real) else "that"
                notify(
                    client_id, "Value changed",
                    f"{_label(handle)} = {sent} is not allowed here: set to {value}{allowed}",
                )  # fmt: skip

    ws.unregister_handler(_messages.GuiUpdateMessage, original)
    ws.register_handler(_messages.GuiUpdateMessage, guarded)
    if max_upload_bytes is not None:
        _guard_uploads(server, notify, max_upload_bytes, upload_doc)


def _guard_uploads(
    server: viser.ViserServer, notify: Notify | None, max_bytes: int, doc: str
) -> None:
    """viser buffers an upload's parts from ``FileTransferStartUpload`` on; refuse it there, by
    its declared size, and drop a transfer whose parts outgrow what it declared."""
    gui = server.gui
    ws = server._websock_server
    start, part = gui._handle_file_transfer_start, gui._handle_file_transfer_part
    states = gui._current_file_upload_states
    see = f" (see {doc})" if doc else ""

    def refuse(client_id: int, message: Any, why: str) -> None:
        # an ack for the whole file ends the browser's progress bar; nothing was stored
        ws.queue_message(
            _messages.FileTransferPartAck(
                source_component_uuid=message.source_component_uuid,
                transfer_uuid=message.transfer_uuid,
                transferred_bytes=int(max(message.size_bytes, 0)),
                total_bytes=int(max(message.size_bytes, 0)),
            )
        )
        if notify is not None:
            notify(client_id, "Upload refused", f"{str(message.filename)[:100]}: {why}{see}")

    def guarded_start(client_id: int, message: Any) -> None:
        size = message.size_bytes
        if not isinstance(size, int) or isinstance(size, bool) or size < 0:
            return refuse(client_id, message, "no valid file size")
        if size == 0:
            return refuse(client_id, message, "the file is empty")
        if size > max_bytes:
            return refuse(
                client_id, message, f"{size} bytes; a preset is at most {max_bytes} bytes"
            )
        return start(client_id, message)

    def guarded_part(client_id: int, message: Any) -> None:
        state = states.get(message.transfer_uuid)
        if state is not None and (
            state["client_id"] != client_id
            or state["transferred_bytes"] + len(message.content) > state["total_bytes"]
        ):
            states.pop(message.transfer_uuid, None)  # lies about its size: forget it
            return None
        return part(client_id, message)

    ws.unregister_handler(_messages.FileTransferStartUpload, start)
    ws.register_handler(_messages.FileTransferStartUpload, guarded_start)
    ws.unregister_handler(_messages.FileTransferPart, part)
    ws.register_handler(_messages.FileTransferPart, guarded_part)
