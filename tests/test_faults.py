"""Faults injected into a running dashboard: a fall, a QP failure, a non-finite state, an exception
in a GUI callback and in the recorder.  Each leaves the server running, its memory where it was
and every tab working; a fall or fault is shown once (a new one replaces the last pop-up) with its
likely cause, and the walk resets.

Tabs are real websocket clients speaking viser's protocol (see ``tests/test_guard.py``); backend
faults come from a session factory whose ``step`` can be told to fail.
"""

from __future__ import annotations

import asyncio
import dataclasses
import threading
from collections.abc import Iterator

import numpy as np
import pytest

viser = pytest.importorskip("viser")
websockets = pytest.importorskip("websockets")

import helpers  # noqa: E402
from test_guard import CAMERA, decode, free_port, tab, update, uuid_of  # noqa: E402

from dcmviz.config import Config  # noqa: E402
from dcmviz.dashboard import Dashboard  # noqa: E402
from dcmviz.session import Session  # noqa: E402


def wait_for(condition, timeout: float = 20.0) -> bool:
    """Wait on the condition, long enough for a loaded machine (the suite shares 2 cores with
    other jobs: a 5 s bound expired once on a fault notification under a load average of 7)."""
    return helpers.wait_for(condition, max(timeout, 20.0))


class Tab:
    """A browser tab in a thread: connects, collects every message until closed."""

    def __init__(self, port: int) -> None:
        self.port = port
        self.messages: list[dict] = []
        self.closed_code: int | None = None
        self.connected = threading.Event()
        self._outbox: list[bytes] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=lambda: asyncio.run(self._run()), daemon=True)
        self._thread.start()
        assert self.connected.wait(10)

    async def _run(self) -> None:
        url = f"ws://127.0.0.1:{self.port}"
        async with websockets.connect(url, subprotocols=[f"viser-v{viser.__version__}"]) as ws:
            await ws.send(CAMERA)
            self.connected.set()
            while not self._stop.is_set():
                while self._outbox:
                    await ws.send(self._outbox.pop(0))
                try:
                    frame = await asyncio.wait_for(ws.recv(), timeout=0.05)
                    self.messages.extend(decode(frame))
                except TimeoutError:
                    pass
                except websockets.ConnectionClosed as closed:
                    self.closed_code = closed.rcvd.code if closed.rcvd else -1
                    return

    def send(self, frame: bytes) -> None:
        self._outbox.append(frame)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)

    def visible_notifications(self, titles: set[str]) -> list[str]:
        """Bodies of the notifications with these titles that were shown and not removed."""
        shown: dict[str, str] = {}
        for m in list(self.messages):
            if m["type"] == "NotificationShowMessage" and m["props"]["title"] in titles:
                shown[m["uuid"]] = m["props"]["body"]
            elif m["type"] == "RemoveNotificationMessage":
                shown.pop(m["uuid"], None)
        return list(shown.values())

    def shown(self, titles: set[str]) -> list[str]:
        return [
            m["props"]["body"]
            for m in list(self.messages)
            if m["type"] == "NotificationShowMessage" and m["props"]["title"] in titles
        ]


class Injector:
    """A session factory whose sessions fail on request: ``inject("qp")`` or ``inject("nan")``."""

    def __init__(self) -> None:
        self.pending: str | None = None

    def inject(self, kind: str) -> None:
        self.pending = kind

    def __call__(self, config: Config) -> Session:
        session = Session(config, backend="lip")
        step = session.step

        def faulty_step():
            kind, self.pending = self.pending, None
            if kind == "qp":
                raise RuntimeError("whole-body QP infeasible (daqp exit -1)")
            command = step()
            if kind == "nan":
                return dataclasses.replace(command, v_cmd=np.full(3, np.nan))
            return command

        session.step = faulty_step
        return session


def rss_mb() -> float:
    with open("/proc/self/status") as f:
        line = next(x for x in f if x.startswith("VmRSS:"))
    return int(line.split()[1]) / 1024.0


@pytest.fixture
def running() -> Iterator[tuple[Dashboard, Injector, int]]:
    injector = Injector()
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    config = Config().replace(sim={"backend": "lip"}, gait={"mode": "continuous"})
    d = Dashboard(server, config, session_factory=injector)
    yield d, injector, server.get_port()
    d.stop()
    server.stop()


def still_working(d: Dashboard, port: int, *tabs: Tab) -> None:
    """The walk runs, every tab is open, a new tab connects, and a control still works."""
    t = d.loop.session.t
    assert wait_for(lambda: d.loop.session.t > t + 0.2)
    assert all(tab_.closed_code is None for tab_ in tabs)
    received, code = tab(port)
    assert code is None and received > 0
    k = d.controls.handles[("control", "k_xi")]
    value = 4.0 if d.config.control.k_xi != 4.0 else 5.0
    tabs[0].send(update(uuid_of(k), {"value": value}))
    assert wait_for(lambda: d.config.control.k_xi == value)


@pytest.mark.parametrize("kind", ["qp", "nan"])
def test_backend_fault_resets_the_walk_and_is_shown_once(running, kind) -> None:
    d, injector, port = running
    tabs = [Tab(port), Tab(port)]
    assert wait_for(lambda: len(d.server.get_clients()) == 2)  # both receive every pop-up
    try:
        titles = {"Simulation fault"}
        tl = d.loop.timeline
        for n in (1, 2):
            assert wait_for(lambda: d.loop.session.t > 0.5)
            walk = tl.walk_of(tl.last_seq)
            injector.inject(kind)
            assert wait_for(lambda n=n: d.loop.faults == n)
            # the walk restarted: the buffer's newest frame is the first walk's after it (its
            # tick index went back to the start), whatever the wall clock did meanwhile
            assert wait_for(lambda walk=walk: tl.walk_of(tl.last_seq) == walk + 1)
            assert wait_for(lambda n=n: all(len(t_.shown(titles)) == n for t_ in tabs))
        for t_ in tabs:
            visible = t_.visible_notifications(titles)
            assert len(visible) == 1  # the second replaced the first
            cause = "QP infeasible" if kind == "qp" else "not finite"
            assert cause in visible[0] and "restarts" in visible[0]
        still_working(d, port, *tabs)
    finally:
        for t_ in tabs:
            t_.close()


def test_fall_is_shown_once_with_its_likely_cause(running) -> None:
    d, _, port = running
    tabs = [Tab(port), Tab(port)]
    assert wait_for(lambda: len(d.server.get_clients()) == 2)  # both receive every pop-up
    try:
        for n in (1, 2):
            assert wait_for(lambda: not d.loop.snapshot.status.fallen and d.loop.session.t > 0.5)
            d.loop.post(
                "push", {"force": (0.0, 2000.0, 0.0), "duration": 0.5, "ramp": 0.0, "body": "torso"}
            )
            assert wait_for(lambda n=n: d.loop.falls == n, timeout=10)
            assert wait_for(lambda n=n: all(len(t_.shown({"Fall"})) == n for t_ in tabs))
        for t_ in tabs:
            visible = t_.visible_notifications({"Fall"})
            assert len(visible) == 1 and "Likely cause: the push" in visible[0]
        assert wait_for(
            lambda: not d.loop.snapshot.status.fallen, timeout=5
        )  # reset after the pause
        still_working(d, port, *tabs)
    finally:
        for t_ in tabs:
            t_.close()


def test_fall_cause_names_the_push_first_then_the_plan_warning(running) -> None:
    """A plan the checker warns about, and a push too large to survive: the fall is the push's
    (issue 25: a recent push is named first; the plan walked before it) and the plan's
    warning is still counted."""
    d, _, port = running
    tab_ = Tab(port)
    assert wait_for(lambda: len(d.server.get_clients()) == 1)
    try:
        assert d.editor.on_field_change("gait", "t_start", 0.2)  # D2 outside the support
        assert wait_for(
            lambda: d.feasibility.source == "the walked plan" and d.feasibility.warnings
        )
        d.loop.post(
            "push", {"force": (0.0, 2000.0, 0.0), "duration": 0.5, "ramp": 0.0, "body": "torso"}
        )
        assert wait_for(lambda: tab_.visible_notifications({"Fall"}), timeout=10)
        text = tab_.visible_notifications({"Fall"})[0]
        assert "Likely cause: the push on the torso at t = " in text, text
        assert "2000 N" in text and "the plan also has 1 feasibility warning" in text, text
    finally:
        tab_.close()


def test_exception_in_a_callback_is_told_and_changes_nothing(running, monkeypatch) -> None:
    d, _, port = running
    tabs = [Tab(port), Tab(port)]
    assert wait_for(lambda: len(d.server.get_clients()) == 2)  # both receive every pop-up
    try:
        n = d.controls.handles[("gait", "n_steps")]

        def broken(*args, **kwargs):
            raise RuntimeError("a bug in a callback")

        monkeypatch.setattr(d.editor, "apply_dict", broken)
        tabs[0].send(update(uuid_of(n), {"value": 7}))
        assert wait_for(lambda: tabs[0].shown({"Internal error"}))
        assert "a bug in a callback" in tabs[0].shown({"Internal error"})[0]
        assert not tabs[1].shown({"Internal error"})  # only the tab that caused it
        assert d.notifier.callback_errors == 1 and d.config.gait.n_steps != 7
        monkeypatch.undo()
        still_working(d, port, *tabs)
    finally:
        for t_ in tabs:
            t_.close()


def test_exception_in_the_recorder_stops_the_recording_not_the_walk(running, monkeypatch) -> None:
    from dcmviz import record

    d, _, port = running
    tabs = [Tab(port)]
    assert wait_for(lambda: len(d.server.get_clients()) == 1)
    try:
        calls = []

        def broken(self, tick):
            calls.append(tick)
            if len(calls) == 20:
                raise OSError("disk full")

        monkeypatch.setattr(record.Recorder, "on_tick", broken)
        tabs[0].send(update(uuid_of(d.recording.gui_record), {"value": True}))
        assert wait_for(lambda: d.recording.failures == 1)
        assert wait_for(lambda: tabs[0].shown({"Recording failed"}))
        assert "disk full" in tabs[0].shown({"Recording failed"})[0]
        assert d.recording.recorder is None and d.recording.gui_record.value is False
        assert wait_for(lambda: d.loop.session.subscribers == ())
        assert d.loop.faults == 0  # the walk never noticed
        still_working(d, port, *tabs)
    finally:
        for t_ in tabs:
            t_.close()


def test_faults_leave_memory_where_it_was(running) -> None:
    d, injector, port = running
    tab_ = Tab(port)
    assert wait_for(lambda: len(d.server.get_clients()) == 1)
    try:

        def faults(count: int) -> None:
            for _ in range(count):
                start = d.loop.faults
                assert wait_for(lambda: d.loop.session.t > 0.2)
                injector.inject("qp" if start % 2 else "nan")
                assert wait_for(lambda start=start: d.loop.faults == start + 1)

        faults(5)  # warm-up: first allocations of every path
        before = rss_mb()
        faults(30)
        assert rss_mb() - before < 30.0
        assert len(d.notifier._sim_shown) <= len(d.server.get_clients())
        still_working(d, port, tab_)
    finally:
        tab_.close()


def test_the_first_viewer_sees_the_walk_from_its_start() -> None:
    """Issue 14, the first minute: a plan-mode walk restarts when the first tab connects (not a
    walk that ended before the page opened); a second tab changes nothing."""
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    d = Dashboard(server, Config().replace(sim={"backend": "lip"}))
    try:
        assert wait_for(lambda: d.loop.session.t > 1.0)
        tl = d.loop.timeline
        walk = tl.walk_of(tl.last_seq)
        first = Tab(server.get_port())
        assert wait_for(lambda: d.loop.resets == 1)
        # from its start: the buffer's newest frame belongs to a new walk (tick index back to 0)
        assert wait_for(lambda: tl.walk_of(tl.last_seq) == walk + 1)
        assert wait_for(lambda: d.loop.session.t > 1.0)
        second = Tab(server.get_port())
        assert wait_for(lambda: len(server.get_clients()) == 2)
        assert d.loop.resets == 1 and d.loop.session.t > 1.0
        first.close()
        second.close()
    finally:
        d.stop()
        server.stop()
