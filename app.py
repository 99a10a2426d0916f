"""dcmviz dashboard: ``python app.py [--preset PATH] [--host 127.0.0.1] [--port 8080]``."""

from __future__ import annotations

import argparse
import ipaddress
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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--preset", type=Path, default=None, help="preset TOML to start with")
    parser.add_argument("--host", default="127.0.0.1", help="bind address (default: loopback)")
    parser.add_argument("--port", type=int, default=8080)
    args = parser.parse_args(argv)
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
        )
    except OSError as err:
        print(f"app.py: cannot listen on {args.host}:{args.port}: {err}", file=sys.stderr)
        return 2
    shown = "localhost" if is_loopback(args.host) else args.host
    print(f"dcmviz dashboard: http://{shown}:{server.get_port()}  (Ctrl-C to stop)", flush=True)
    if not is_loopback(args.host):
        print(
            f"WARNING: listening on {args.host}, beyond this machine. Anyone who can reach "
            f"port {server.get_port()} can control the simulation (change every setting, push "
            "the robot, upload presets) for everyone watching; there is no login. Use the "
            "default --host 127.0.0.1 unless you trust that network.",
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
