"""The sweep's command line: ``python -m dcmviz.sweep`` (see :mod:`dcmviz.sweep`); exit 0 done,
2 for bad input with a one-line reason."""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from dcmviz.cli import BadInput, Parser, fraction, positive_int, positive_seconds
from dcmviz.config import ConfigError, load_preset
from dcmviz.sweep.experiments import CONTROLLERS, SweepSettings, envelope, ramp_test
from dcmviz.sweep.report import ramp_table, table, write_envelope
from dcmviz.sweep.search import push_window

PROG = "dcmviz.sweep"


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog=PROG, description="Push-recovery envelopes by bisection (see module doc).")
    p.add_argument("preset", help="preset TOML file")
    p.add_argument("--sim", choices=("lip", "mujoco"), default=None, help="default: lip")
    p.add_argument("--directions", type=positive_int, default=8, help="evenly spaced, 0 = +x")
    p.add_argument("--push-duration", type=positive_seconds, default=0.2, help="s")
    p.add_argument("--phase", type=fraction, default=0.5, help="fraction of single support")
    p.add_argument("--step", type=positive_int, default=4, help="which step (1-based) is pushed")
    p.add_argument(
        "--settle-steps", type=positive_seconds, default=3.0, help="step periods after the push"
    )
    p.add_argument("--full", action="store_true", help="walk to the end of the plan instead")
    p.add_argument("--max-impulse", type=positive_seconds, default=150.0, help="bracket top, N·s")
    p.add_argument("--grid", type=positive_int, default=6, help="coarse grid points")
    p.add_argument("--iterations", type=positive_int, default=7, help="bisection iterations")
    p.add_argument("--jobs", type=positive_int, default=os.cpu_count() or 1)
    p.add_argument(
        "--controllers",
        default=",".join(CONTROLLERS),
        help=f"comma-separated subset of {', '.join(CONTROLLERS)}",
    )
    p.add_argument("--out", default="sweep_out", help="output directory")
    p.add_argument(
        "--ramp-test",
        action="store_true",
        help="bisect the held force of the preset's ramped push instead",
    )
    p.add_argument("--max-force", type=positive_seconds, default=400.0, help="ramp test, N")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """CLI entry point; returns the exit status (0 done, 2 bad input)."""
    try:
        try:
            args = build_parser().parse_args(argv)
        except SystemExit as exc:  # --help
            return int(exc.code or 0)
        controllers = tuple(c.strip() for c in args.controllers.split(",") if c.strip())
        for c in controllers:
            if c not in CONTROLLERS:
                raise BadInput(f"--controllers {c!r}: allowed {', '.join(CONTROLLERS)}")
        config = load_preset(args.preset)
        settings = SweepSettings(
            backend=args.sim or "lip",
            directions=args.directions,
            push_duration_s=args.push_duration,
            phase=args.phase,
            step=args.step,
            settle_steps=args.settle_steps,
            full=args.full,
            max_impulse_ns=args.max_impulse,
            grid=args.grid,
            iterations=args.iterations,
            jobs=args.jobs,
            controllers=controllers,
        )
        if not args.ramp_test:
            push_window(config, settings.step, settings.phase)  # validates --step
        out = Path(args.out)
        if out.exists() and not out.is_dir():
            raise BadInput(f"--out {args.out!r}: exists and is not a directory")
    except (BadInput, ConfigError, ValueError) as exc:
        print(f"{PROG}: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    if args.ramp_test:
        try:
            result = ramp_test(config, settings, max_force_n=args.max_force)
        except BadInput as exc:
            print(f"{PROG}: error: {exc}", file=sys.stderr)
            return 2
        out.mkdir(parents=True, exist_ok=True)
        (out / "ramp.json").write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
        print(ramp_table(result))
        print(f"wrote {out / 'ramp.json'}")
        return 0
    result = envelope(config, settings)
    paths = write_envelope(result, out)
    print(table(result))
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0
