"""Notifications: to the client that caused an event, or to every client when none did."""

from __future__ import annotations

import functools
import threading
import traceback
from collections import deque
from collections.abc import Callable
from typing import Any

import viser

NOTIFY_S = 4.0  # seconds an information stays up
ERROR_NOTIFY_S = 8.0  # seconds an error stays up


def _client_of(arg: Any) -> viser.ClientHandle | None:
    """The client of a GUI event, or the client passed as an argument."""
    if isinstance(arg, viser.ClientHandle):
        return arg
    client = getattr(arg, "client", None)
    return client if isinstance(client, viser.ClientHandle) else None


class Notifier:
    """Sends notifications and keeps the latest (title, body) pairs for tests and the log."""

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        # bounded: a hostile client cannot grow it
        self.notifications: deque[tuple[str, str]] = deque(maxlen=200)
        self.callback_errors = 0  # exceptions caught in GUI callbacks (tests watch it)
        self._sim_shown: dict[int, Any] = {}  # client id → its fall/fault notification
        self._lock = threading.Lock()

    def notify(
        self, client: viser.ClientHandle | None, title: str, body: str, *, error: bool = False
    ) -> None:
        """A notification to one client (or all clients when the event has none)."""
        self.notifications.append((title, body))
        clients = [client] if client is not None else list(self.server.get_clients().values())
        for c in clients:
            try:
                c.add_notification(
                    title, body, auto_close_seconds=ERROR_NOTIFY_S if error else NOTIFY_S,
                    color="red" if error else "blue",
                )  # fmt: skip
            except Exception:  # noqa: BLE001 - a client that just closed
                pass

    def notify_client_id(self, client_id: int, title: str, body: str) -> None:
        """An error to the client with this id (the guard's refusals)."""
        client = self.server.get_clients().get(client_id)
        if client is not None:
            self.notify(client, title, body, error=True)

    def on_sim_event(self, kind: str, message: str) -> None:
        """A fall or a simulation fault, for everyone: one notification per tab at a time (a new
        fall replaces the last one instead of stacking pop-ups)."""
        title = "Fall" if kind == "fell" else "Simulation fault"
        self.notifications.append((title, message))
        with self._lock:
            clients = self.server.get_clients()
            for client_id in list(self._sim_shown):
                if client_id not in clients:
                    self._sim_shown.pop(client_id)
            for client_id, client in clients.items():
                try:
                    old = self._sim_shown.pop(client_id, None)
                    if old is not None:
                        old.remove()
                    self._sim_shown[client_id] = client.add_notification(
                        title, message, auto_close_seconds=ERROR_NOTIFY_S, color="red"
                    )
                except Exception:  # noqa: BLE001 - a client that just closed
                    pass

    def guarded(self, name: str, callback: Callable[..., Any]) -> Callable[..., Any]:
        """``callback`` for a GUI event; an exception in it is told to the client that caused it
        (and printed once), and the dashboard carries on."""

        @functools.wraps(callback)
        def run(*args: Any, **kwargs: Any) -> Any:
            try:
                return callback(*args, **kwargs)
            except Exception as err:  # noqa: BLE001 - a bug in one callback must not spread
                self.callback_errors += 1
                client = next((c for c in map(_client_of, args) if c is not None), None)
                print(f"dcmviz: {name} failed: {err!r}\n{traceback.format_exc(limit=3)}")
                self.notify(
                    client, "Internal error", f"{name} failed ({err!r}); the dashboard carries "
                    "on. Please report it with the traceback the server printed.", error=True,
                )  # fmt: skip
                return None

        return run
