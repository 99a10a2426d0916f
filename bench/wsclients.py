"""Non-rendering dashboard clients: N websocket connections that count what the server sends.

    python3 bench/wsclients.py PORT N SECONDS [--warmup S] [--drag UUID LO HI HZ]
    python3 bench/wsclients.py --room N [--seconds S] [--preset PATH]

``--room N`` (issue 26): starts ``app.py`` with a presenter key in its own process, connects the
presenter's tab (with the key) and reads the real-time factor its status line shows, first alone
for S seconds, then with N watching tabs (without the key) connected; prints both, and what each
watcher receives.  The walk stays at x1 when the two medians agree.

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
import re
import socket
import statistics
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

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


REAL_TIME = re.compile(r"real-time ×\s*([0-9.]+)")
ROOT = Path(__file__).resolve().parents[1]


async def frames(url: str, until: float):
    """A tab's connection (viser's subprotocol, its camera first): the binary frames it is sent
    until ``until`` (monotonic time)."""
    async with websockets.connect(
        url, subprotocols=[f"viser-v{viser.__version__}"], max_size=None
    ) as ws:
        await ws.send(CAMERA)
        while (now := time.monotonic()) < until:
            try:
                frame = await asyncio.wait_for(ws.recv(), timeout=until - now)
            except TimeoutError:
                break
            if not isinstance(frame, str):
                yield frame


async def presenter(url: str, until: float, factors: list[tuple[float, float]]) -> None:
    """The presenter's tab: records (time, real-time factor) from every status update."""
    async for frame in frames(url, until):
        for m in decode(frame)[0]:
            if m.get("type") != "GuiUpdateMessage":
                continue
            if (match := REAL_TIME.search(str(m.get("updates")))) is not None:
                factors.append((time.monotonic(), float(match.group(1))))


async def watcher(url: str, until: float) -> int:
    """A watching tab that reads everything it is sent (like a browser) and decodes nothing."""
    received = 0
    async for frame in frames(url, until):
        received += len(frame)
    return received


async def room_run(port: int, key: str, n: int, seconds: float) -> dict:
    base = f"ws://127.0.0.1:{port}"
    factors: list[tuple[float, float]] = []
    t0 = time.monotonic()
    warm, alone_end = t0 + 5.0, t0 + 5.0 + seconds
    end = alone_end + seconds
    task = asyncio.create_task(presenter(f"{base}/?key={key}", end, factors))
    await asyncio.sleep(alone_end - time.monotonic())
    received = await asyncio.gather(*(watcher(base, end) for _ in range(n)))
    await task

    def median(lo: float, hi: float) -> tuple[float, float, int]:
        xs = [f for t, f in factors if lo <= t < hi]
        return (statistics.median(xs), min(xs), len(xs)) if xs else (float("nan"), 0.0, 0)

    alone, crowd = median(warm, alone_end), median(alone_end + 3.0, end)
    return {
        "watchers": n, "seconds": seconds,
        "real_time_alone": {"median": alone[0], "min": alone[1], "samples": alone[2]},
        "real_time_watched": {"median": crowd[0], "min": crowd[1], "samples": crowd[2]},
        "ratio": crowd[0] / alone[0] if alone[2] and crowd[2] else float("nan"),
        "kib_per_s_per_watcher": sum(received) / max(n, 1) / 1024 / seconds,
    }  # fmt: skip


def room(n: int, seconds: float, preset: Path) -> dict:
    from dcmviz.dashboard.audience import new_key

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    key = new_key()
    cmd = [sys.executable, str(ROOT / "app.py"), "--host", "127.0.0.1", "--port", str(port),
           "--key", key, "--max-tabs", str(n + 5), "--preset", str(preset)]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and "watch" not in (proc.stdout.readline() or "watch"):
            pass
        return asyncio.run(room_run(port, key, n, seconds))
    finally:
        proc.terminate()
        proc.wait(timeout=20)


if __name__ == "__main__" and "--room" in sys.argv:
    n = int(sys.argv[sys.argv.index("--room") + 1])
    seconds = float(sys.argv[sys.argv.index("--seconds") + 1]) if "--seconds" in sys.argv else 30.0
    preset = (
        Path(sys.argv[sys.argv.index("--preset") + 1])
        if "--preset" in sys.argv
        else ROOT / "presets" / "walk_forward.toml"
    )
    r = room(n, seconds, preset)
    a, w = r["real_time_alone"], r["real_time_watched"]
    print(f"{preset.stem}: real time, presenter alone  x{a['median']:.2f} (min x{a['min']:.2f})")
    print(f"{preset.stem}: with {n} watching tabs     x{w['median']:.2f} (min x{w['min']:.2f}); "
          f"ratio {r['ratio']:.2f}; {r['kib_per_s_per_watcher']:.0f} KiB/s to each watcher")  # fmt: skip
    print(json.dumps(r))
elif __name__ == "__main__":
    port, n, seconds = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
    warmup = float(sys.argv[sys.argv.index("--warmup") + 1]) if "--warmup" in sys.argv else 3.0
    dragging = None
    if "--drag" in sys.argv:
        i = sys.argv.index("--drag")
        uuid, lo, hi, hz = sys.argv[i + 1 : i + 5]
        dragging = (uuid, float(lo), float(hi), float(hz))
    print(json.dumps(asyncio.run(main(port, n, seconds, warmup, dragging))))
