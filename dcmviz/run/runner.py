"""Headless runner: ``python -m dcmviz.run PRESET [--sim lip|mujoco] [--duration S] [--json PATH]
[--rrd PATH] [--csv PATH] [--set section.key=value ...]`` (DESIGN.md, "Headless runner").

Runs a preset without a browser, prints a short summary and optionally writes a JSON result and a
rerun recording.  Exit status 0 for a completed run (a fall is a result, not an error), 2 for bad
input with a one-line reason on stderr.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dcmviz.config import Config, ConfigError, apply_overrides, load_preset
from dcmviz.gait.feasibility import check_plan
from dcmviz.run.args import BadInput, Parser, positive_seconds
from dcmviz.run.logs import CsvLog, TickLog, push_recovery
from dcmviz.session import Session

PROG = "dcmviz.run"
ADJUSTMENT_REPORTED_M = 1e-3  # footsteps that landed ≥ 1 mm from the plan count as adjusted


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog=PROG, description="Run a dcmviz preset headless and summarise the walk.")
    p.add_argument("preset", help="preset TOML file (see presets/)")
    p.add_argument("--sim", choices=("lip", "mujoco"), help="backend (default: the preset's)")
    p.add_argument(
        "--duration", type=positive_seconds, help="simulated seconds (default: sim.duration)"
    )
    p.add_argument("--json", metavar="PATH", help="write the result as JSON")
    p.add_argument("--rrd", metavar="PATH", help="write a rerun recording (.rrd)")
    p.add_argument("--csv", metavar="PATH", help="write one row per control tick (CSV)")
    p.add_argument(
        "--set",
        metavar="section.key=value",
        action="append",
        default=[],
        dest="overrides",
        help="override a preset value (TOML literal), e.g. --set control.observer=false",
    )
    return p


# ---------------------------------------------------------------------------------------------
# running


def load_config(preset: str, overrides: Sequence[str]) -> Config:
    """Preset + ``--set`` overrides, or ConfigError with one line."""
    config = load_preset(preset)
    return apply_overrides(config, list(overrides)) if overrides else config


def run_session(
    session: Session,
    *,
    duration: float | None = None,
    rrd: str | Path | None = None,
    csv_path: str | Path | None = None,
    preset_path: str | None = None,
) -> dict[str, Any]:
    """Run a session's walk from its start and return the result dict (the ``--json`` content).

    A fall ends the run early and is reported, never raised.
    """
    config = session.config
    robot = session.robot
    warnings = [  # the walked plan; its crossed footsteps are checked against the robot's region
        str(w) for w in check_plan(session.plan, session.spec, config, lambda: robot.crossover)
    ]
    log = TickLog()
    unsubscribe = [session.subscribe(log)]
    csv_log = CsvLog(csv_path) if csv_path is not None else None
    if csv_log is not None:
        unsubscribe.append(session.subscribe(csv_log))
    recorder = None
    if rrd is not None:
        from dcmviz.record import Recorder

        recorder = Recorder()
        recorder.start(session, rrd)
    duration = config.sim.duration if duration is None else duration
    try:
        metrics = session.run(duration, stop_on_fall=True)
    finally:
        if recorder is not None:
            recorder.stop()
        for u in unsubscribe:
            u()
        if csv_log is not None:
            csv_log.close()
    sim_time = float(session.t)
    wall = float(metrics.wall_time_s)
    t, err = np.asarray(log.t), np.asarray(log.error)
    records = session.realised_steps()
    adjustments = [
        {"t": float(a["t"]), "step": int(a["step"]), "dx": a["dx"], "dy": a["dy"]}
        for a in session.step_adjustments
        if math.hypot(a["dx"], a["dy"]) >= ADJUSTMENT_REPORTED_M
    ]
    result: dict[str, Any] = {
        "preset": config.name,
        "preset_path": preset_path,
        "backend": session.backend_name,
        "robot": config.robot.model,
        "mass_kg": float(session.mass),
        "requested_duration_s": duration,
        "fell": bool(metrics.fell),
        "fall_time_s": metrics.fall_time_s,
        "sim_time_s": sim_time,
        "wall_time_s": wall,
        "real_time_factor": sim_time / wall if wall > 0 else None,
        "ticks": metrics.ticks,
        "steps_planned": len(session.nominal_plan.steps) if config.gait.mode == "plan" else None,
        "steps_completed": int(session.steps_completed),
        "max_dcm_error_m": float(metrics.max_dcm_error_m),
        "final_dcm_error_m": float(metrics.final_dcm_error_m),
        "step_adjustments": adjustments,
        "max_step_adjustment_m": max(
            (math.hypot(a["dx"], a["dy"]) for a in adjustments), default=0.0
        ),
        "footsteps": [
            {
                "t": float(r.t),
                "step": int(r.step),
                "side": r.side,
                "position": [float(v) for v in r.position],
                "nominal": [float(v) for v in r.nominal],
            }
            for r in records
        ],
        "pushes": push_recovery(config.pushes, t, err, [r.t for r in records], metrics.fall_time_s),
        "control": config.control.model_dump(),
        "dcm": config.dcm.model_dump(),
        "rrd": str(rrd) if rrd is not None else None,
        "warnings": warnings,
    }
    return result


def summary(result: dict[str, Any]) -> str:
    """A few human-readable lines."""
    outcome = (
        f"FELL at t = {result['fall_time_s']:.2f} s" if result["fell"] else "walked without falling"
    )
    rtf = result["real_time_factor"]
    lines = [
        f"{result['preset']} [{result['robot']}, {result['backend']}]: {outcome}",
        f"  sim {result['sim_time_s']:.2f} s in {result['wall_time_s']:.2f} s wall"
        + (f" ({rtf:.1f}x real time)" if rtf else ""),
        f"  steps {result['steps_completed']}"
        + (f"/{result['steps_planned']}" if result["steps_planned"] is not None else "")
        + f", adjusted {len(result['step_adjustments'])}"
        f" (max {result['max_step_adjustment_m'] * 100:.1f} cm)",
        f"  DCM error max {result['max_dcm_error_m'] * 100:.2f} cm,"
        f" final {result['final_dcm_error_m'] * 100:.2f} cm",
    ]
    lines += [f"  warning: {w}" for w in result.get("warnings", ())]
    for i, p in enumerate(result["pushes"]):
        peak = p["max_dcm_error_m"]
        rec = p["recovery_time_1cm_s"]
        lines.append(
            f"  push {i} at {p['start_s']:.2f} s, |F| {np.linalg.norm(p['force_n']):.0f} N"
            f" for {p['duration_s']:.2f} s: "
            + ("not reached" if not p["reached"] else f"peak error {peak * 100:.1f} cm, ")
            + (
                ""
                if not p["reached"]
                else (
                    "not back under 1 cm"
                    if rec is None
                    else f"< 1 cm {rec:.2f} s after it ({p['recovery_steps_1cm']} steps)"
                )
            )
        )
    return "\n".join(lines)


def _check_output(path: str | None, flag: str) -> None:
    if path is None:
        return
    parent = Path(path).resolve().parent
    if not parent.is_dir():
        raise BadInput(f"{flag} {path!r}: directory {str(parent)!r} does not exist")
    if Path(path).is_dir():
        raise BadInput(f"{flag} {path!r}: is a directory, expected a file path")


def main(argv: Sequence[str] | None = None) -> int:
    """CLI entry point; returns the exit status (0 done, 2 bad input)."""
    parser = build_parser()
    try:
        try:
            args = parser.parse_args(argv)
        except SystemExit as exc:  # --help
            return int(exc.code or 0)
        _check_output(args.json, "--json")
        _check_output(args.rrd, "--rrd")
        _check_output(args.csv, "--csv")
        config = load_config(args.preset, args.overrides)
        session = Session(config, backend=args.sim)
    except (BadInput, ConfigError, ValueError) as exc:
        message = " ".join(str(exc).split())  # one line, whatever the source
        print(f"{PROG}: error: {message}", file=sys.stderr)
        return 2
    result = run_session(
        session, duration=args.duration, rrd=args.rrd, csv_path=args.csv, preset_path=args.preset
    )
    print(summary(result))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    return 0
