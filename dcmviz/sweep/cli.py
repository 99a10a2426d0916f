"""The sweep's command line: ``python -m dcmviz.sweep`` (see :mod:`dcmviz.sweep`); exit 0 done,
2 for bad input with a one-line reason, 130 when interrupted (finished rollouts are kept in
``OUT/rollouts.jsonl``; ``--resume`` continues from them)."""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from dcmviz.config import ConfigError, load_preset
from dcmviz.run.args import BadInput, Parser, fraction, positive_int, positive_seconds
from dcmviz.sweep.experiments import (
    CONTROLLERS,
    PRESET_CONTROLLER,
    STRATEGIES,
    Execution,
    SweepSettings,
    envelope,
    ramp_test,
)
from dcmviz.sweep.maps import gain_map, parse_axis, write_map
from dcmviz.sweep.report import METRICS, ramp_table, table, write_envelope
from dcmviz.sweep.search import push_window
from dcmviz.sweep.store import ROLLOUTS_FILE, RolloutStore

PROG = "dcmviz.sweep"


def add_execution_args(p: argparse.ArgumentParser) -> None:
    """--jobs, --address, --no-progress (shared with dcmviz.sweep.tune)."""
    p.add_argument(
        "--jobs",
        type=positive_int,
        default=None,
        help="CPUs of the local Ray instance (default: all); 1 runs serially without Ray",
    )
    p.add_argument("--address", default=None, help="a running Ray cluster (ray start), host:port")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def add_envelope_args(p: argparse.ArgumentParser, *, directions: int = 8) -> None:
    """The push and search settings of an envelope (shared with dcmviz.sweep.tune)."""
    p.add_argument("--sim", choices=("lip", "mujoco"), default=None, help="default: lip")
    p.add_argument("--directions", type=positive_int, default=directions, help="evenly spaced")
    p.add_argument("--push-duration", type=positive_seconds, default=0.2, help="s")
    p.add_argument("--phase", type=fraction, default=0.5, help="fraction of single support")
    p.add_argument("--step", type=positive_int, default=4, help="which step (1-based) is pushed")
    p.add_argument(
        "--settle-steps", type=positive_seconds, default=3.0, help="step periods after the push"
    )
    p.add_argument("--full", action="store_true", help="walk to the end of the plan instead")
    p.add_argument("--max-impulse", type=positive_seconds, default=150.0, help="bracket top, N·s")
    p.add_argument("--coarse", type=positive_int, default=6, help="coarse grid points")
    p.add_argument("--iterations", type=positive_int, default=7, help="bisection iterations")


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog=PROG, description="Push-recovery envelopes and gain maps (see module doc).")
    p.add_argument("preset", help="preset TOML file")
    add_envelope_args(p)
    add_execution_args(p)
    p.add_argument(
        "--controllers",
        default=None,
        help=f"comma-separated subset of {', '.join([*CONTROLLERS, PRESET_CONTROLLER])} "
        f"(default: the three; with --grid: {PRESET_CONTROLLER}, the preset's own flags)",
    )
    p.add_argument(
        "--strategies",
        default=None,
        help=f"compare recovery strategies side by side: comma-separated subset of "
        f"{', '.join(STRATEGIES)} (each with step adjustment on, observer off), after tracking; "
        "one table and one polar plot with a curve per strategy (replaces --controllers)",
    )
    p.add_argument("--out", default="sweep_out", help="output directory")
    p.add_argument(
        "--resume",
        action="store_true",
        help=f"reuse the finished rollouts in OUT/{ROLLOUTS_FILE} (else it is started afresh)",
    )
    p.add_argument(
        "--grid",
        nargs="+",
        metavar="KEY=START:STOP:COUNT",
        default=None,
        help="gain map over one or two preset keys, e.g. control.k_xi=1:6:6 dcm.b=0.28:0.32:3",
    )
    p.add_argument(
        "--metric", choices=METRICS, default="weakest", help="map value (default weakest)"
    )
    p.add_argument(
        "--ramp-test",
        action="store_true",
        help="bisect the held force of the preset's ramped push instead",
    )
    p.add_argument("--max-force", type=positive_seconds, default=400.0, help="ramp test, N")
    return p


def settings_from_args(args: argparse.Namespace, controllers: tuple[str, ...]) -> SweepSettings:
    if args.address is not None and args.jobs is not None:
        raise BadInput("--jobs sets the CPUs of a local Ray instance; leave it out with --address")
    return SweepSettings(
        backend=args.sim or "lip",
        directions=args.directions,
        push_duration_s=args.push_duration,
        phase=args.phase,
        step=args.step,
        settle_steps=args.settle_steps,
        full=args.full,
        max_impulse_ns=args.max_impulse,
        grid=args.coarse,
        iterations=args.iterations,
        jobs=args.jobs or os.cpu_count() or 1,
        controllers=controllers,
        address=args.address,
    )


def parse_controllers(text: str) -> tuple[str, ...]:
    names = tuple(c.strip() for c in text.split(",") if c.strip())
    for c in names:
        if c not in CONTROLLERS and c != PRESET_CONTROLLER and c not in STRATEGIES:
            allowed = ", ".join([*CONTROLLERS, PRESET_CONTROLLER, *STRATEGIES])
            raise BadInput(f"--controllers {c!r}: allowed {allowed}")
    if not names:
        raise BadInput("--controllers: name at least one")
    return names


def parse_strategies(text: str) -> tuple[str, ...]:
    names = tuple(c.strip() for c in text.split(",") if c.strip())
    for c in names:
        if c not in STRATEGIES:
            raise BadInput(f"--strategies {c!r}: allowed {', '.join(STRATEGIES)}")
    if not names:
        raise BadInput("--strategies: name at least one")
    return names


def _error(exc: BaseException) -> int:
    print(f"{PROG}: error: {' '.join(str(exc).split())}", file=sys.stderr)
    return 2


def check_step(config, settings) -> None:
    """BadInput naming ``--step`` if the preset's plan has no such step."""
    try:
        push_window(config, settings.step, settings.phase)
    except ValueError as err:
        raise BadInput(f"--{err}") from None


def main(argv: Sequence[str] | None = None) -> int:
    """CLI entry point; returns the exit status (0 done, 2 bad input, 130 interrupted)."""
    try:
        try:
            args = build_parser().parse_args(argv)
        except SystemExit as exc:  # --help
            return int(exc.code or 0)
        default = PRESET_CONTROLLER if args.grid else ",".join(CONTROLLERS)
        if args.strategies is not None:
            if args.controllers is not None:
                raise BadInput("--strategies replaces --controllers: give one of them")
            controllers = ("tracking", *parse_strategies(args.strategies))
        else:
            controllers = parse_controllers(args.controllers or default)
        config = load_preset(args.preset)
        settings = settings_from_args(args, controllers)
        axes = [parse_axis(a, config) for a in args.grid] if args.grid else []
        if len(axes) > 2:
            raise BadInput(f"--grid: give one or two keys, got {len(axes)}")
        if not args.ramp_test:
            check_step(config, settings)
        out = Path(args.out)
        if out.exists() and not out.is_dir():
            raise BadInput(f"--out {args.out!r}: exists and is not a directory")
    except (BadInput, ConfigError, ValueError) as exc:
        return _error(exc)
    out.mkdir(parents=True, exist_ok=True)
    store = RolloutStore(out / ROLLOUTS_FILE, resume=args.resume)
    if store.loaded:
        print(f"resuming: {store.loaded} finished rollouts in {store.path}", file=sys.stderr)
    execution = Execution(store=store, progress=not args.no_progress)
    try:
        if args.ramp_test:
            result = ramp_test(config, settings, max_force_n=args.max_force, execution=execution)
            (out / "ramp.json").write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
            print(ramp_table(result))
            paths = [out / "ramp.json"]
        elif axes:
            result = gain_map(config, axes, settings, metric=args.metric, execution=execution)
            paths = write_map(result, out)
            print(map_summary(result))
        else:
            result = envelope(config, settings, execution)
            paths = write_envelope(result, out)
            print(table(result))
    except (BadInput, ConfigError, ValueError, ConnectionError) as exc:
        return _error(exc)
    except KeyboardInterrupt:
        print(
            f"\n{PROG}: interrupted; {len(store)} finished rollouts are in {store.path}: "
            "run the same command with --resume to continue",
            file=sys.stderr,
        )
        return 130
    finally:
        store.close()
    counts = result["rollouts"]
    print(
        f"{counts['run']} rollouts run ({counts['runner']}), {counts['from_store']} from "
        f"{store.path}"
    )
    print("wrote " + ", ".join(str(p) for p in [*paths, store.path]))
    return 0


def map_summary(result: dict) -> str:
    """The map as text: the metric per point and controller, the preset's point named."""
    keys = [a["key"] for a in result["axes"]]
    metric = result["metric"]
    lines = [
        f"{metric} push impulse (N·s) over the map; preset at "
        + ", ".join(f"{k}={v}" for k, v in zip(keys, result["preset_point"], strict=True)),
        " ".join(f"{k:>16}" for k in keys) + f" {'controller':>26} {metric:>10}",
    ]
    for e in result["values"]:
        lines.append(
            " ".join(f"{e[k]:>16g}" for k in keys) + f" {e['controller']:>26} {e[metric]:10.2f}"
        )
    best = max(result["values"], key=lambda e: e[metric])
    lines.append("best: " + ", ".join(f"{k}={best[k]}" for k in keys) + f" ({best[metric]:.2f})")
    return "\n".join(lines)
