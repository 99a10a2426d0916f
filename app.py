"""dcmviz dashboard: ``python app.py [--preset PATH] [--host 127.0.0.1] [--port 8080]``.

For a room: ``python app.py --host 0.0.0.0`` prints a presenter URL (with a random key, or
``--key`` / $DCMVIZ_KEY) and a watch URL; tabs without the key watch (dcmviz.dashboard.audience).
"""

from __future__ import annotations

import argparse
import ipaddress
import os
import socket
import sys
import time
from pathlib import Path

from dcmviz.config import Config, ConfigError, load_preset

ROOT = Path(__file__).resolve().parent
DEFAULT_PRESET = ROOT / "presets" / "walk_forward.toml"


def is_loopback(host: str) -> bool:
    """True for an address only this machine can reach (127.0.0.0/8, ::1, localhost)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def reachable_name(host: str) -> str:
    """The name to print in URLs: localhost for loopback, this machine's address for 0.0.0.0."""
    if is_loopback(host):
        return "localhost"
    if host in ("0.0.0.0", "::", ""):
        try:  # the address this machine uses towards the network (no packet is sent)
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
                s.connect(("192.0.2.1", 9))
                return s.getsockname()[0]
        except OSError:
            return socket.gethostname()
    return host


def print_qr(url: str) -> None:
    """The watch URL as a QR code in the terminal (phones in the room scan it)."""
    import segno

    segno.make(url, error="m").terminal(compact=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--preset", type=Path, default=None, help="preset TOML to start with")
    parser.add_argument("--host", default="127.0.0.1", help="bind address (default: loopback)")
    parser.add_argument("--port", type=int, default=8080)
    parser.add_argument(
        "--key", default=None,
        help="presenter key (default: $DCMVIZ_KEY, or a random one when --host is not loopback); "
        "tabs without it only watch",
    )  # fmt: skip
    parser.add_argument(
        "--public-url", default=None,
        help="the address the room reaches, e.g. https://demo.example.org behind a TLS proxy "
        "(default: http://HOST:PORT)",
    )  # fmt: skip
    parser.add_argument(
        "--max-tabs", type=int, default=50, help="most watching tabs at once (default 50)"
    )
    parser.add_argument(
        "--fig1a", choices=("stream", "panel"), default=None,
        help="stream: Fig. 1a in a frame of its own, fed from the next free port after --port "
        "(forward both ports through a tunnel); panel: in viser's plots, slower where the 3-D "
        "scene renders slowly (default: stream, panel with --public-url)",
    )  # fmt: skip
    parser.add_argument(
        "--audience-push", action="store_true",
        help="watchers may push the robot by clicking it (one push per 3 s per tab)",
    )  # fmt: skip
    args = parser.parse_args(argv)
    # (viser and the dashboard load only once the arguments are good)
    from dcmviz.dashboard.audience import (
        KEY_ENV,
        base_url,
        check_key,
        new_key,
        presenter_url,
        watch_url,
    )  # fmt: skip

    path = args.preset if args.preset is not None else DEFAULT_PRESET
    try:
        if args.preset is not None or DEFAULT_PRESET.exists():
            config = load_preset(path)
        else:
            config = Config()
    except ConfigError as err:
        print(f"app.py: {err}", file=sys.stderr)
        return 2
    if not 0 < args.port < 65536:
        print(f"app.py: --port {args.port}: must be in 1..65535", file=sys.stderr)
        return 2
    if args.public_url is not None and not args.public_url.startswith(("http://", "https://")):
        print(f"app.py: --public-url {args.public_url}: must start with http:// or https://",
              file=sys.stderr)  # fmt: skip
        return 2
    if args.max_tabs < 1:
        print(f"app.py: --max-tabs {args.max_tabs}: must be at least 1", file=sys.stderr)
        return 2
    key = args.key if args.key is not None else os.environ.get(KEY_ENV) or None
    if key is None and not is_loopback(args.host):
        key = new_key()
    if key is not None:
        try:
            check_key(key)
        except ValueError as err:
            print(f"app.py: --key: {err}", file=sys.stderr)
            return 2

    from dcmviz.dashboard import serve

    try:
        presets = ROOT / "presets"
        in_presets = path.resolve().parent == presets.resolve() and path.exists()
        server, dashboard = serve(
            config,
            host=args.host,
            port=args.port,
            presets_dir=presets,
            preset=path.stem if in_presets else "(current)",
            key=key,
            max_tabs=args.max_tabs,
            audience_push=args.audience_push,
            fig1a=args.fig1a or ("panel" if args.public_url else "stream"),
        )
    except OSError as err:
        print(f"app.py: cannot listen on {args.host}:{args.port}: {err}", file=sys.stderr)
        return 2
    port = server.get_port()
    if key is None:
        shown = "localhost" if is_loopback(args.host) else args.host
        print(f"dcmviz dashboard: http://{shown}:{port}  (Ctrl-C to stop)", flush=True)
    else:
        base = args.public_url or base_url(reachable_name(args.host), port)
        print(
            f"dcmviz dashboard (Ctrl-C to stop), {args.max_tabs} watching tabs at most", flush=True
        )
        print(
            f"  presenter (controls; keep it private): {presenter_url(base, key)}",
            flush=True,
        )
        print(f"  watch (the room; no controls):          {watch_url(base)}", flush=True)
        if not is_loopback(args.host):
            print_qr(watch_url(base))
            print(
                f"Listening on {args.host}: anyone who can reach port {port} can watch"
                + (" and push the robot (--audience-push)" if args.audience_push else "")
                + "; only a tab opened with the presenter URL controls the simulation. The "
                "connection is plain http/ws: put a TLS proxy in front of it on networks you "
                "do not trust (README, 'A demo for a room').",
                flush=True,
            )
    if dashboard.fig1a_stream is not None:
        print(
            f"  Fig. 1a streams from port {dashboard.fig1a_stream.port} (forward it too)",
            flush=True,
        )
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        dashboard.stop()
        server.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
