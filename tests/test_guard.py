"""Hostile and malformed websocket messages, sent through a real websocket client.

Before the guard, one ``n = 1e30`` closed every connection (old and new) with code 1011 until the
server was restarted.  These tests speak viser's own wire protocol (msgpack, the ``viser-v…``
subprotocol) to a real server and check that every tab keeps working.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable, Iterator

import msgspec
import pytest
import zstandard

viser = pytest.importorskip("viser")
websockets = pytest.importorskip("websockets")

from helpers import free_port, wait_for  # noqa: E402

from dcmviz.config import Config  # noqa: E402
from dcmviz.dashboard import Dashboard  # noqa: E402
from dcmviz.dashboard.guard import Rejected, clean_value  # noqa: E402


@pytest.fixture
def served() -> Iterator[tuple[viser.ViserServer, Dashboard]]:
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    d = Dashboard(server, Config().replace(sim={"backend": "lip"}), start=False)
    assert d.preview.wait(0)
    yield server, d
    d.stop()
    server.stop()


def uuid_of(handle) -> str:
    return handle._impl.uuid  # the test needs the wire id of a control


CAMERA = msgspec.msgpack.encode(
    {
        "type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0], "position": [3.0, -2.0, 1.5],
        "fov": 1.0, "near": 0.01, "far": 100.0, "image_height": 600, "image_width": 800,
        "look_at": [0.0, 0.0, 0.5], "up_direction": [0.0, 0.0, 1.0],
    }
)  # fmt: skip  # a browser tab announces its camera first; viser counts it as connected then


def update(uuid: str, updates: dict) -> bytes:
    return msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": uuid, "updates": updates})


def decode(frame: bytes) -> list[dict]:
    """The messages in one server frame (viser's layout: sizes, zstd msgpack, binary buffers)."""
    n_compressed = int.from_bytes(frame[8:16], "little")
    n_inner = int.from_bytes(frame[0:8], "little")
    inner = zstandard.ZstdDecompressor().decompress(
        frame[16 : 16 + n_compressed], max_output_size=n_inner
    )
    return list(msgspec.msgpack.decode(inner)["messages"])


Until = Callable[[list[dict]], bool]


async def _session(
    port: int, frames: list[bytes | str], until: Until, timeout: float, seen: list[dict]
) -> tuple[int, int | None]:
    """Connect like a browser tab, send ``frames``, listen until ``until(messages)`` holds (or
    ``timeout`` s); (frames received, close code)."""
    url = f"ws://127.0.0.1:{port}"
    received = 0
    async with websockets.connect(url, subprotocols=[f"viser-v{viser.__version__}"]) as ws:
        await ws.send(CAMERA)
        for frame in frames:
            await ws.send(frame)
        deadline = time.monotonic() + timeout
        try:
            while (left := deadline - time.monotonic()) > 0 and not (received and until(seen)):
                try:
                    frame = await asyncio.wait_for(ws.recv(), timeout=left)
                    received += 1
                    seen.extend(decode(frame))
                except TimeoutError:
                    break
        except websockets.ConnectionClosed as closed:
            return received, closed.rcvd.code if closed.rcvd else -1
    return received, None


def tab(
    port: int, frames=(), until: Until | None = None, seen: list[dict] | None = None,
    timeout: float = 10.0,
) -> tuple[int, int | None]:  # fmt: skip
    """A tab's session: by default it ends with the first frame the server sends (the state);
    give ``until`` to wait for what a sent frame causes (a notification, the server's state:
    viser runs a control's callbacks only while its sender is connected)."""
    seen = [] if seen is None else seen
    return asyncio.run(_session(port, list(frames), until or (lambda m: True), timeout, seen))


def notified(title: str) -> Until:
    """The tab was shown a notification whose title contains ``title``."""
    return lambda messages: any(
        m["type"] == "NotificationShowMessage" and title in m["props"]["title"] for m in messages
    )


def shown_value(messages: list[dict], uuid: str):
    """The value a tab displays for a control after applying ``messages`` in order."""
    value = None
    for m in messages:
        if m.get("uuid") == uuid and "value" in m and m["type"] != "GuiUpdateMessage":
            value = m["value"]  # the control's creation message
        if m["type"] == "GuiUpdateMessage" and m.get("uuid") == uuid:
            value = m["updates"].get("value", value)
    return value


def test_huge_integer_is_clamped_and_every_tab_keeps_working(served) -> None:
    server, d = served
    port = server.get_port()
    n = d.controls.handles[("gait", "n_steps")]
    seen: list[dict] = []
    received, code = tab(
        port, [update(uuid_of(n), {"value": 1e30})], seen=seen,
        until=lambda m: shown_value(m, uuid_of(n)) == int(n.max),
    )  # fmt: skip
    assert code is None and received > 0
    # clamped to the control's range (what validation accepts), then applied as a config
    assert wait_for(lambda: d.config.gait.n_steps == int(n.max))
    assert n.value == int(n.max) and isinstance(n.value, int)
    assert shown_value(seen, uuid_of(n)) == int(n.max)  # the sender shows the stored value
    # a new tab connects, receives the whole state (the same n) and stays open
    seen = []
    received, code = tab(port, seen=seen, until=lambda m: shown_value(m, uuid_of(n)) == int(n.max))
    assert code is None and received > 0
    assert shown_value(seen, uuid_of(n)) == int(n.max)


@pytest.mark.parametrize(
    "updates",
    [
        {"value": float("nan")},
        {"value": float("inf")},
        {"value": "abc"},
        {"value": [1, 2]},
        {"value": 2.5},  # n is a whole number
        {"sync_cb": "x"},  # viser would write any attribute onto the handle
        {"removed": True},
        {"value": 12, "label": "hijacked"},
        {},
    ],
)
def test_malformed_values_are_refused_and_state_is_kept(served, updates) -> None:
    server, d = served
    n = d.controls.handles[("gait", "n_steps")]
    before_value, before_label, version = n.value, n.label, d.version
    received, code = tab(server.get_port(), [update(uuid_of(n), updates)], notified("refused"))
    assert code is None and received > 0
    assert wait_for(lambda: d.notifications and "refused" in d.notifications[-1][0])
    assert (n.value, n.label, d.version) == (before_value, before_label, version)
    # the control still works for everyone afterwards
    tab(server.get_port(), [update(uuid_of(n), {"value": 7})], lambda m: d.config.gait.n_steps == 7)
    assert wait_for(lambda: d.config.gait.n_steps == 7)
    assert tab(server.get_port())[1] is None


def test_garbage_frames_close_only_the_sender(served) -> None:
    server, d = served
    port = server.get_port()
    for frame in (b"\x00\xff garbage", msgspec.msgpack.encode({"type": "NoSuchMessage"}), "text"):
        tab(port, [frame])
    n = d.controls.handles[("gait", "n_steps")]
    tab(port, [update("no-such-uuid", {"value": 3}), update(uuid_of(n), {"value": 9})],
        lambda m: d.config.gait.n_steps == 9)  # fmt: skip
    assert wait_for(lambda: d.config.gait.n_steps == 9)
    received, code = tab(port)
    assert code is None and received > 0


def test_clean_value_per_control_kind(served) -> None:
    _, d = served
    b = d.controls.handles[("dcm", "b")]
    assert clean_value(b, 10.0) == b.max and clean_value(b, -3) == b.min
    order = d.controls.handles[("dcm", "order")]
    assert clean_value(order, "3") == "3"
    with pytest.raises(Rejected, match="allowed 0, 1, 3, 5"):
        clean_value(order, "4")
    observer = d.controls.handles[("control", "observer")]
    with pytest.raises(Rejected, match="true or false"):
        clean_value(observer, 1)


def test_representation_is_not_a_change_but_a_clamp_is(served) -> None:
    """80 for a float slider is 80.0 and a dragged 3.1000000000000005 is 3.1: stored quietly;
    a value beyond the range is clamped and the sender is told."""
    server, d = served
    port = server.get_port()
    magnitude = d.push_panel.gui_push_magnitude
    k = d.controls.handles[("control", "k_xi")]
    before = len(d.notifications)
    frames = [update(uuid_of(magnitude), {"value": 80}), update(uuid_of(k), {"value": 3.1 + 4e-16})]
    tab(port, frames, lambda m: magnitude.value == 80.0 and d.config.control.k_xi != 3.0)
    assert wait_for(lambda: magnitude.value == 80.0 and d.config.control.k_xi == pytest.approx(3.1))
    assert isinstance(magnitude.value, float)
    assert not any(title == "Value changed" for title, _ in list(d.notifications)[before:])
    tab(port, [update(uuid_of(magnitude), {"value": 6000.0})], notified("Value changed"))
    assert wait_for(lambda: d.notifications and d.notifications[-1][0] == "Value changed")
    assert magnitude.value == magnitude.max and str(magnitude.max) in d.notifications[-1][1]


def upload_start(button, size: int, parts: int = 1, name: str = "big.toml") -> bytes:
    return msgspec.msgpack.encode(
        {
            "type": "FileTransferStartUpload", "source_component_uuid": uuid_of(button),
            "transfer_uuid": f"t-{size}", "filename": name, "mime_type": "text/plain",
            "part_count": parts, "size_bytes": size,
        }
    )  # fmt: skip


def upload_part(button, size: int, index: int, content: bytes) -> bytes:
    return msgspec.msgpack.encode(
        {
            "type": "FileTransferPart", "source_component_uuid": uuid_of(button),
            "transfer_uuid": f"t-{size}", "part_index": index, "content": content,
        }
    )  # fmt: skip


@pytest.mark.parametrize("size", [5 * 1024 * 1024, 0])
def test_uploads_refused_by_size_before_they_are_read(served, size) -> None:
    """A 5 MB upload is refused from its first message (viser stores none of its parts); an
    empty one too; the refusal points to the preset documentation in the repository."""
    server, d = served
    button = d.preset_panel.gui_upload
    before = d.config
    frames = [upload_start(button, size, parts=max(1, size // 1_000_000))]
    frames += [upload_part(button, size, 0, b"#" * 1_000_000)] if size else []
    tab(server.get_port(), frames, notified("Upload refused"))
    assert wait_for(lambda: d.notifications and d.notifications[-1][0] == "Upload refused")
    body = d.notifications[-1][1]
    assert ("empty" in body if size == 0 else str(size) in body) and "docs/presets.md" in body
    assert server.gui._current_file_upload_states == {}  # nothing buffered
    assert d.config is before


def test_upload_that_outgrows_its_declared_size_is_dropped(served) -> None:
    server, d = served
    button = d.preset_panel.gui_upload
    frames = [upload_start(button, 100, parts=2), upload_part(button, 100, 0, b"#" * 90),
              upload_part(button, 100, 1, b"#" * 50_000)]  # fmt: skip
    n = d.controls.handles[("gait", "n_steps")]  # handled after the parts: its echo ends the tab
    tab(server.get_port(), [*frames, update(uuid_of(n), {"value": 5})],
        lambda m: d.config.gait.n_steps == 5)  # fmt: skip
    assert wait_for(lambda: server.gui._current_file_upload_states == {})
    assert not any(title == "Preset loaded" for title, _ in d.notifications)
