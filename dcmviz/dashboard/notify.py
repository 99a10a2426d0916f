"""Notifications: to the client that caused an event, or to every client when none did."""

from __future__ import annotations

from collections import deque

import viser

NOTIFY_S = 4.0  # seconds an information stays up
ERROR_NOTIFY_S = 8.0  # seconds an error stays up


class Notifier:
    """Sends notifications and keeps the latest (title, body) pairs for tests and the log."""

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        # bounded: a hostile client cannot grow it
        self.notifications: deque[tuple[str, str]] = deque(maxlen=200)

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
        """A fall or a simulation error, for everyone."""
        self.notify(None, "Fall" if kind == "fell" else "Simulation", message, error=True)
