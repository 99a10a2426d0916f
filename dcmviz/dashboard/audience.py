"""A demo for a room: the presenter's tab controls, every other tab watches.

``python app.py --host 0.0.0.0`` prints two addresses.  The watch URL is the dashboard's page;
the presenter URL is the same page told to open its websocket with the presenter's key
(``?websocket=ws://host:port/?key=K``: viser's page connects to the ``websocket`` address it is
given, and the key travels only in that connection's request line).  A tab whose connection
carries the right key (compared with :func:`hmac.compare_digest`) is a presenter; any other tab,
a wrong key included, is a watcher.  Without a key (loopback, no ``--key``) every tab is a
presenter, as before.

Watchers see everything live (scene, robot, plots, status, notifications), but the server
drops every message a watcher's tab sends before viser or the dashboard sees it: GUI values,
buttons, uploads, forms, scene clicks and drags, share requests.  Only the tab's own camera
(which viser keeps per tab) reaches the server.  With ``audience_push`` a watcher may push the
robot by clicking it, at most once per ``push_interval_s``; the push's force and duration are the
presenter's settings (validated like a preset's) and the status line names the watcher.

Limits that keep a demo up: at most ``max_tabs`` watchers (a tab beyond it gets a page saying
the demo is full and is refused like a watcher; presenters are always let in), and per tab at
most ``rate`` messages a second on average (``burst`` at once); beyond it messages are dropped
and the tab is told once.

viser has no public hook for incoming messages or for the address a tab connected with, so
this module, like :mod:`.guard`, reaches into ``ViserServer._websock_server``
(``_handle_incoming_message``, ``_live_connections``); ``tests/test_audience.py`` speaks the
wire protocol to a real server and fails if a viser upgrade moves them.
"""

from __future__ import annotations

import hmac
import logging
import secrets
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import parse_qs, quote, urlsplit

import viser
from viser import _messages

KEY_PARAM = "key"
KEY_ENV = "DCMVIZ_KEY"  # the presenter key from the environment (app.py --key wins)
MIN_KEY_CHARS = 8
PRESENTER, WATCHER, OVER = "presenter", "watcher", "over the limit"
# what a watching tab may send: its own camera (viser keeps one per tab; the aim arrow follows it)
VIEW_ONLY = (_messages.ViewerCameraMessage,)
WELCOME_DELAY_S = 1.5  # after its view is up, a watching tab is told so (and its panel greyed)

Notify = Callable[[int, str, str], None]  # (client id, title, body)


def new_key() -> str:
    """A random presenter key (128 bits, URL-safe)."""
    return secrets.token_urlsafe(16)


def check_key(key: str) -> str:
    """``key`` if it can be a presenter key, else ValueError naming what is allowed."""
    if len(key) < MIN_KEY_CHARS or not all(c.isalnum() or c in "-_." for c in key):
        raise ValueError(
            f"the presenter key must be at least {MIN_KEY_CHARS} characters of letters, digits, "
            "'-', '_' or '.' (it goes into a URL)"
        )
    return key


class _Redact(logging.Filter):
    """Replaces the key in log records of the websocket layer (its debug log writes each
    request line, the presenter's ``/?key=…`` included)."""

    def __init__(self, key: str) -> None:
        super().__init__()
        self.key = key

    def filter(self, record: logging.LogRecord) -> bool:
        text = record.getMessage()
        if self.key in text:
            record.msg, record.args = text.replace(self.key, "<presenter key>"), None
        return True


REDACTED_LOGGERS = ("websockets.server", "websockets.protocol", "websockets", "viser")


def base_url(host: str, port: int) -> str:
    return f"http://{host}:{port}"


def watch_url(base: str) -> str:
    """The page for the room (``base``: ``http(s)://host[:port]``, as the room reaches it)."""
    return base.rstrip("/") + "/"


def presenter_url(base: str, key: str) -> str:
    """The page, told to open its websocket with the key (viser's ``websocket`` parameter);
    behind a TLS proxy (an ``https`` base) the websocket is ``wss``."""
    base = base.rstrip("/")
    socket_url = "ws" + base.removeprefix("http") + f"/?{KEY_PARAM}={key}"
    return f"{base}/?websocket=" + quote(socket_url)


def key_of(path: str) -> str | None:
    """The key a websocket's request path carries (``/?key=K``), if any."""
    values = parse_qs(urlsplit(path).query).get(KEY_PARAM, ())
    return values[0] if len(values) == 1 else None


@dataclass
class _Tab:
    role: str
    tokens: float
    refill_t: float = field(default_factory=time.monotonic)
    last_push_t: float = -1e9
    told_t: float = -1e9  # when the tab was last told why a message was dropped
    number: int = 0  # watchers are numbered in the order they came (status line)


class Audience:
    """Roles per tab and the filter in front of viser's message dispatch (module docstring)."""

    def __init__(
        self,
        server: viser.ViserServer,
        key: str | None = None,
        *,
        max_tabs: int = 50,
        audience_push: bool = False,
        push_interval_s: float = 3.0,
        rate: float = 100.0,
        burst: float = 400.0,
        notify: Notify | None = None,
    ) -> None:
        if max_tabs < 1:
            raise ValueError(f"max_tabs = {max_tabs}: must be at least 1")
        if push_interval_s < 0 or rate <= 0 or burst < 1:
            raise ValueError("push_interval_s must be >= 0, rate > 0 and burst >= 1")
        self.server = server
        self._key = None if key is None else check_key(key)
        self.max_tabs = max_tabs
        self.audience_push = audience_push
        self.push_interval_s = push_interval_s
        self.rate, self.burst = rate, burst
        self.notify = notify
        self.dropped = 0  # messages dropped (tests and the bench read it)
        self._tabs: dict[int, _Tab] = {}
        self._watchers_seen = 0
        self._lock = threading.Lock()
        ws = server._websock_server
        self._ws = ws
        self._dispatch = ws._handle_incoming_message
        ws._handle_incoming_message = self._filtered  # instance attribute: before the class's
        ws.on_client_connect(self._opened)
        ws.on_client_disconnect(self._closed)
        server.on_client_connect(self._viewing)
        if self._key is not None:
            self._redact = _Redact(self._key)
            for name in REDACTED_LOGGERS:
                logging.getLogger(name).addFilter(self._redact)

    def close(self) -> None:
        """Stops redacting this key from the log (the server stopped)."""
        if self._key is not None:
            for name in REDACTED_LOGGERS:
                logging.getLogger(name).removeFilter(self._redact)

    # -- who is who ------------------------------------------------------------------------------
    @property
    def keyed(self) -> bool:
        """A key is set: tabs without it watch."""
        return self._key is not None

    def role(self, client_id: int) -> str:
        tab = self._tabs.get(client_id)
        return tab.role if tab is not None else WATCHER

    def may_control(self, client_id: int) -> bool:
        return self.role(client_id) == PRESENTER

    def label(self, client: viser.ClientHandle | None) -> str:
        """'' for a presenter (or no client), 'watcher N' for a watcher."""
        if client is None:
            return ""
        tab = self._tabs.get(client.client_id)
        if tab is None or tab.role == PRESENTER:
            return ""
        return f"watcher {tab.number}"

    def counts(self) -> dict[str, int]:
        out = {PRESENTER: 0, WATCHER: 0, OVER: 0}
        for tab in list(self._tabs.values()):
            out[tab.role] += 1
        return out

    def _is_presenter_key(self, path: str) -> bool:
        if self._key is None:
            return True
        sent = key_of(path)
        if sent is None:
            return False
        return hmac.compare_digest(sent.encode(), self._key.encode())

    # -- connections -----------------------------------------------------------------------------
    def _opened(self, connection: Any) -> None:
        client_id = connection.client_id
        socket = self._ws._live_connections.get(client_id)
        request = getattr(socket, "request", None)
        path = getattr(request, "path", "") or ""
        with self._lock:
            if self._is_presenter_key(path):
                role = PRESENTER
            elif self.counts()[WATCHER] >= self.max_tabs:
                role = OVER
            else:
                role = WATCHER
            tab = _Tab(role, self.burst)
            if role != PRESENTER:
                self._watchers_seen += 1
                tab.number = self._watchers_seen
            self._tabs[client_id] = tab

    def _closed(self, connection: Any) -> None:
        with self._lock:
            self._tabs.pop(connection.client_id, None)

    def _viewing(self, client: viser.ClientHandle) -> None:
        """The tab's view is up: a watcher is told it watches, one over the limit that the demo
        is full (a modal over the whole page)."""
        role = self.role(client.client_id)
        if role == OVER:
            with client.gui.add_modal("This demo is full"):
                client.gui.add_markdown(
                    f"{self.max_tabs} tabs are already watching (the presenter's `--max-tabs`). "
                    "Close this tab and try again later, or ask the presenter to raise the limit."
                )
        if role != PRESENTER and self.keyed:
            self._disable_controls(client)
            # once more, and the welcome, when the tab has surely drawn its panel: viser replays
            # the GUI on its own channel, which may still be running when the camera arrives
            timer = threading.Timer(WELCOME_DELAY_S, self._welcome, (client, role))
            timer.daemon = True
            timer.start()

    def _welcome(self, client: viser.ClientHandle, role: str) -> None:
        self._disable_controls(client)
        if role != WATCHER or client.client_id not in self.server.get_clients():
            return
        how = (
            f"Click the robot to push it (one push per {self.push_interval_s:g} s)."
            if self.audience_push
            else "Only the presenter can change settings or push the robot."
        )
        try:
            client.add_notification(
                "Watching", f"You are watching the presenter's walk. {how}",
                auto_close_seconds=10.0, color="gray",
            )  # fmt: skip
        except Exception:  # noqa: BLE001 - a tab that just closed
            pass

    def _disable_controls(self, client: viser.ClientHandle) -> None:
        """Every control on this tab greyed out (its own copy of the panel; others keep theirs)."""
        if client.client_id not in self.server.get_clients():
            return
        try:
            for uuid in list(self.server.gui._gui_input_handle_from_uuid):
                client._websock_connection.queue_message(
                    _messages.GuiUpdateMessage(uuid, {"disabled": True})
                )
        except Exception:  # noqa: BLE001 - a tab that just closed
            pass

    # -- the filter ------------------------------------------------------------------------------
    async def _filtered(self, client_id: int, message: Any) -> None:
        why = self._refusal(client_id, message)
        if why is None:
            await self._dispatch(client_id, message)
            return
        self.dropped += 1
        if isinstance(message, _messages.GuiUpdateMessage):
            self._restore(client_id, message)
        tab = self._tabs.get(client_id)
        now = time.monotonic()
        if (
            tab is not None
            and now - tab.told_t > 2.0
            and self.notify is not None
            and client_id in self.server.get_clients()  # (its view is up: it can be told)
        ):
            tab.told_t = now
            self.notify(client_id, "Not sent", why)

    def _refusal(self, client_id: int, message: Any) -> str | None:
        """Why ``message`` from this tab is dropped, or None when it passes."""
        tab = self._tabs.get(client_id)
        if tab is None:
            return "this connection is not known"
        now = time.monotonic()
        tab.tokens = min(self.burst, tab.tokens + (now - tab.refill_t) * self.rate)
        tab.refill_t = now
        if tab.tokens < 1.0:
            return f"more than {self.rate:g} messages a second from this tab; slow down"
        tab.tokens -= 1.0
        if tab.role == PRESENTER or isinstance(message, VIEW_ONLY):
            return None
        if tab.role == OVER:
            return f"the demo is full ({self.max_tabs} tabs)"
        if self.audience_push and isinstance(message, _messages.SceneNodeClickMessage):
            if now - tab.last_push_t < self.push_interval_s:
                wait = self.push_interval_s - (now - tab.last_push_t)
                return f"one push per {self.push_interval_s:g} s: wait {wait:.1f} s"
            tab.last_push_t = now
            return None
        return "you are watching: only the presenter's tab changes the demo"

    def _restore(self, client_id: int, message: Any) -> None:
        """A watcher's control snaps back: its tab is sent the value everybody else sees."""
        handle = self.server.gui._gui_input_handle_from_uuid.get(message.uuid)
        client = self.server.get_clients().get(client_id)
        if handle is None or client is None:
            return
        try:
            value = handle.value
            client._websock_connection.queue_message(
                _messages.GuiUpdateMessage(message.uuid, {"value": value})
            )
        except Exception:  # noqa: BLE001 - a tab that just closed, or a value viser cannot send
            pass
