"""Automatic tuning of a preset's gains and timing (Ray Tune + Optuna):

    python -m dcmviz.sweep.tune PRESET --objective weakest|area|tracking --trials N [--seed S]
        [--sim lip|mujoco] [--out DIR] [--jobs N | --address HOST:PORT] [envelope options]

writes ``OUT/best.toml`` (the best preset; ``dcmviz.config.load_preset`` loads it),
``OUT/tune.json`` (every trial) and ``OUT/tune.png`` (the objective over the trials and the
best envelope against the starting one).  Exit 0 done, 2 for bad input, 130 when interrupted.
The search itself is :mod:`dcmviz.sweep.tuning`.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from dcmviz.config import ConfigError, load_preset
from dcmviz.run.args import BadInput, Parser, positive_int, positive_seconds
from dcmviz.sweep.cli import add_envelope_args, add_execution_args, check_step, settings_from_args
from dcmviz.sweep.experiments import PRESET_CONTROLLER
from dcmviz.sweep.tuning import OBJECTIVES, TuneSettings, tune_preset, write_tuning

PROG = "dcmviz.sweep.tune"


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog=PROG, description="Tune a preset's gains and timing (Ray Tune + Optuna).")
    p.add_argument("preset", help="preset TOML file")
    p.add_argument("--objective", choices=tuple(OBJECTIVES), default="weakest")
    p.add_argument("--trials", type=positive_int, default=20)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--probe-impulse", type=positive_seconds, default=15.0, help="tracking objective, N·s"
    )
    p.add_argument("--out", default="tune_out", help="output directory")
    add_envelope_args(p)
    add_execution_args(p)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """CLI entry point; returns the exit status (0 done, 2 bad input, 130 interrupted)."""
    try:
        try:
            args = build_parser().parse_args(argv)
        except SystemExit as exc:  # --help
            return int(exc.code or 0)
        config = load_preset(args.preset)
        settings = settings_from_args(args, (PRESET_CONTROLLER,))
        check_step(config, settings)
        out = Path(args.out)
        if out.exists() and not out.is_dir():
            raise BadInput(f"--out {args.out!r}: exists and is not a directory")
    except (BadInput, ConfigError, ValueError) as exc:
        print(f"{PROG}: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    tune_settings = TuneSettings(args.objective, args.trials, args.seed, args.probe_impulse)
    try:
        result = tune_preset(config, tune_settings, settings, out, progress=not args.no_progress)
    except ConnectionError as exc:
        print(f"{PROG}: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"\n{PROG}: interrupted", file=sys.stderr)
        return 130
    paths = write_tuning(result, out)
    print(summary(result))
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


def summary(result: dict) -> str:
    unit, start, best = result["unit"], result["start"], result["best"]
    lines = [
        f"{result['objective']} ({'max' if result['mode'] == 'max' else 'min'}imise, {unit}), "
        f"{len(result['trials'])} trials, seed {result['seed']}, {result['wall_time_s']:.0f} s",
        f"{'':>28} {'start':>10} {'best':>10}",
        f"{'objective':>28} {start['objective']:10.4g} {best['objective']:10.4g}",
    ]
    for key in best["params"]:
        lines.append(f"{key:>28} {start['params'][key]:10.4g} {best['params'][key]:10.4g}")
    return "\n".join(lines)


if __name__ == "__main__":
    os.environ.setdefault("RAY_AIR_NEW_OUTPUT", "0")
    sys.exit(main())
