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


def install_guard(server: viser.ViserServer, notify: Notify | None = None) -> None:
    """Filter every incoming GUI update of ``server`` through :func:`clean_value`.

    ``notify(client_id, title, body)`` tells the sender why a value was refused or changed.
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
        changed = value != updates["value"] or type(value) is not type(updates["value"])
        message.updates = {"value": value}
        await original(client_id, message)
        if changed:  # the sender still shows what it typed: send everyone the stored value
            ws.queue_message(_messages.GuiUpdateMessage(message.uuid, {"value": value}))
            if notify is not None:
                notify(client_id, "Value changed", f"{_label(handle)} set to {value}")

    ws.unregister_handler(_messages.GuiUpdateMessage, original)
    ws.register_handler(_messages.GuiUpdateMessage, guarded)
