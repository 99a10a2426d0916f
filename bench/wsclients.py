"""Non-rendering dashboard clients: N websocket connections that count what the server sends.

    python3 bench/wsclients.py PORT N SECONDS [--warmup S] [--drag UUID LO HI HZ]

Each connects like a browser tab (viser's subprotocol, a camera message first), skips the
initial state for ``--warmup`` seconds, then counts frames, bytes and messages (decoded: zstd +
msgpack) by type for SECONDS, and prints one JSON line: a list with one dict per client.
``--drag``: the first client also drags the slider UUID back and forth between LO and HI,
HZ updates a second (what a browser sends while a slider is dragged).  Run in
its own process so decoding does not compete with the server for the GIL.
"""

from __future__ import annotations

import asyncio
import json
import sys
import time
from collections import Counter

import msgspec
import viser
import websockets
import zstandard

CAMERA = msgspec.msgpack.encode(
    {
        "type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0], "position": [3.0, -2.0, 1.5],
        "fov": 1.0, "near": 0.01, "far": 100.0, "image_height": 600, "image_width": 800,
        "look_at": [0.0, 0.0, 0.5], "up_direction": [0.0, 0.0, 1.0],
    }
)  # fmt: skip


def decode(frame: bytes) -> tuple[list[dict], list[int]]:
    """The messages in one server frame (viser's layout: sizes, zstd msgpack, binary buffers)
    and the lengths of the binary buffers their arrays point to."""
    n_inner = int.from_bytes(frame[0:8], "little")
    n_compressed = int.from_bytes(frame[8:16], "little")
    inner = zstandard.ZstdDecompressor().decompress(
        frame[16 : 16 + n_compressed], max_output_size=n_inner
    )
    body = msgspec.msgpack.decode(inner)
    return list(body["messages"]), list(body.get("binaryBufferLengths", ()))


def array_bytes(value: object, lengths: list[int]) -> int:
    """Bytes of the binary buffers a decoded message refers to."""
    if isinstance(value, dict):
        if "__binary_index" in value:
            return lengths[value["__binary_index"]]
        return sum(array_bytes(v, lengths) for v in value.values())
    if isinstance(value, list | tuple):
        return sum(array_bytes(v, lengths) for v in value)
    return 0


def message_key(m: dict) -> str:
    """Type, and for updates the node or control they touch (to find who sends most)."""
    kind = m.get("type", "?")
    name = m.get("name") or m.get("uuid") or ""
    if "updates" in m:
        kind += "(" + ",".join(sorted(m["updates"])) + ")"
    return f"{kind} {name}".strip()


def _by_type(sizes: Counter[str]) -> Counter[str]:
    out: Counter[str] = Counter()
    for key, n in sizes.items():
        out[key.split(" ")[0]] += n
    return out


def slider_update(uuid: str, value: float) -> bytes:
    return msgspec.msgpack.encode(
        {"type": "GuiUpdateMessage", "uuid": uuid, "updates": {"value": value}}
    )


async def drag(ws, uuid: str, lo: float, hi: float, hz: float, until: float) -> int:
    """Triangle wave between lo and hi, one full sweep every 2 s; returns updates sent."""
    sent, t0 = 0, time.monotonic()
    while (now := time.monotonic()) < until:
        phase = ((now - t0) / 2.0) % 1.0
        frac = 2 * phase if phase < 0.5 else 2 - 2 * phase
        await ws.send(slider_update(uuid, round(lo + (hi - lo) * frac, 3)))
        sent += 1
        await asyncio.sleep(1.0 / hz)
    return sent


async def client(port: int, warmup_s: float, seconds: float, dragging=None) -> dict:
    url = f"ws://127.0.0.1:{port}"
    counts: Counter[str] = Counter()
    sizes: Counter[str] = Counter()  # msgpack (before zstd) + array bytes by kind
    frames = nbytes = messages = binary = 0
    async with websockets.connect(
        url, subprotocols=[f"viser-v{viser.__version__}"], max_size=None
    ) as ws:
        await ws.send(CAMERA)
        t0 = time.monotonic()
        start, end = t0 + warmup_s, t0 + warmup_s + seconds
        dragger = None
        if dragging is not None:
            dragger = asyncio.create_task(drag(ws, *dragging, until=end))
        while (now := time.monotonic()) < end:
            try:
                frame = await asyncio.wait_for(ws.recv(), timeout=end - now)
            except TimeoutError:
                break
            if time.monotonic() < start or isinstance(frame, str):
                continue
            frames += 1
            nbytes += len(frame)
            binary += len(frame) - 16 - int.from_bytes(frame[8:16], "little")
            msgs, lengths = decode(frame)
            messages += len(msgs)
            for m in msgs:
                key = message_key(m)
                counts[key] += 1
                sizes[key] += len(msgspec.msgpack.encode(m)) + array_bytes(m, lengths)
        drags = await dragger if dragger is not None else 0
    return {
        "drag_updates": drags,
        "frames_per_s": frames / seconds,
        "messages_per_s": messages / seconds,
        "kib_per_s": nbytes / 1024 / seconds,
        "seconds": seconds,
        "binary_kib_per_s": binary / 1024 / seconds,  # array buffers outside the zstd part
        "top": counts.most_common(40),
        "top_bytes": sizes.most_common(20),
        "by_type": sorted(((k, v) for k, v in _by_type(sizes).items()), key=lambda kv: -kv[1]),
        "uncompressed_kib_per_s": sum(sizes.values()) / 1024 / seconds,
    }


async def main(port: int, n: int, seconds: float, warmup_s: float, dragging=None) -> list[dict]:
    return list(
        await asyncio.gather(
            *(client(port, warmup_s, seconds, dragging if i == 0 else None) for i in range(n))
        )
    )


if __name__ == "__main__":
    port, n, seconds = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
    warmup = float(sys.argv[sys.argv.index("--warmup") + 1]) if "--warmup" in sys.argv else 3.0
    dragging = None
    if "--drag" in sys.argv:
        i = sys.argv.index("--drag")
        uuid, lo, hi, hz = sys.argv[i + 1 : i + 5]
        dragging = (uuid, float(lo), float(hi), float(hz))
    print(json.dumps(asyncio.run(main(port, n, seconds, warmup, dragging))))
