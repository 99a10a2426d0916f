"""Headless runner: ``python -m dcmviz.run PRESET [--sim lip|mujoco] [--duration S] [--json PATH]
[--rrd PATH] [--csv PATH] [--set section.key=value ...]`` (DESIGN.md, "Headless runner").

Runs a preset without a browser, prints a short summary and optionally writes a JSON result and a
rerun recording.  Exit status 0 for a completed run (a fall is a result, not an error), 2 for bad
input with a one-line reason on stderr.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dcmviz.cli import BadInput, Parser, positive_seconds
from dcmviz.config import Config, ConfigError, Push, apply_overrides, load_preset
from dcmviz.gait.feasibility import check_plan
from dcmviz.session import Session
from dcmviz.tick import Tick

PROG = "dcmviz.run"
RECOVERY_THRESHOLDS_M = (0.01, 0.02)  # DCM error levels reported per push (1 cm, 2 cm)
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
# per-tick log and push-recovery analysis


@dataclass
class TickLog:
    """Time and DCM error of every tick (the session's history is a bounded ring buffer)."""

    t: list[float] = field(default_factory=list)
    error: list[float] = field(default_factory=list)

    def __call__(self, tick: Tick) -> None:
        self.t.append(tick.t)
        self.error.append(tick.dcm_error_m)  # this tick's |ξ − ξ_ref|


CSV_VECTORS = ("xi", "xi_ref", "xi_adj", "v_ref", "v_cmd", "com", "f_ext", "f_hat")
CSV_COLUMNS = ("t", *(f"{v}_{a}" for v in CSV_VECTORS for a in "xyz"), "support")


class CsvLog:
    """``--csv``: one row per control tick, written as the walk runs (columns ``CSV_COLUMNS``).

    ``xi``/``xi_ref``/``xi_adj``/``v_ref``/``v_cmd`` are the walker's (eqs. 1, 48, 33, 47, 41),
    ``com`` the measured CoM after the tick, ``f_ext`` the applied and ``f_hat`` the estimated
    external force (N), ``support`` the scheduled support (``left``/``right``/``double``).
    """

    def __init__(self, path: str | Path) -> None:
        self._file = open(path, "w", newline="", encoding="utf-8")  # noqa: SIM115 - closed in close()
        self._writer = csv.writer(self._file)
        self._writer.writerow(CSV_COLUMNS)

    def __call__(self, tick: Tick) -> None:
        c = tick.command
        row: list[Any] = [repr(tick.t)]
        for v in (c.xi, c.xi_ref, c.xi_adj, c.v_ref, c.v_cmd, tick.state.com, tick.f_ext, c.f_hat):
            row += [repr(float(v[0])), repr(float(v[1])), repr(float(v[2]))]
        row.append(tick.support)
        self._writer.writerow(row)

    def close(self) -> None:
        self._file.close()


def push_recovery(
    pushes: Sequence[Push],
    t: np.ndarray,
    error: np.ndarray,
    touchdowns: Sequence[float],
    fall_time_s: float | None,
) -> list[dict[str, Any]]:
    """Per push: peak DCM error, and how long / how many steps until it is back under 1 and 2 cm.

    A push's window runs from its start to the next push's start (or the end of the run).  The
    error is "back under" a threshold at the first instant after the push ends from which it stays
    below the threshold to the end of the window; ``None`` if it never does (or the robot fell).
    Steps are touchdowns after the push ends, up to that instant.
    """
    order = sorted(range(len(pushes)), key=lambda i: pushes[i].start)
    t_run_end = float(t[-1]) if len(t) else 0.0
    touch = np.asarray(sorted(touchdowns), dtype=float)
    results: list[dict[str, Any]] = [{} for _ in pushes]
    for rank, i in enumerate(order):
        push = pushes[i]
        t0, t1 = push.start, push.start + push.duration
        w_end = pushes[order[rank + 1]].start if rank + 1 < len(order) else t_run_end + 1.0
        in_push = (t >= t0) & (t < t1)
        in_window = (t >= t0) & (t < w_end)
        res: dict[str, Any] = {
            "start_s": t0,
            "duration_s": push.duration,
            "force_n": list(push.force),
            "ramp_s": push.ramp,
            "impulse_ns": float(np.linalg.norm(push.force)) * (push.duration - 0.5 * push.ramp),
            "reached": bool(len(t) and t[-1] >= t0),
            "max_dcm_error_during_push_m": float(error[in_push].max()) if in_push.any() else None,
            "max_dcm_error_m": float(error[in_window].max()) if in_window.any() else None,
        }
        fell_in_window = fall_time_s is not None and fall_time_s < w_end
        after = (t >= t1) & (t < w_end)
        for thr in RECOVERY_THRESHOLDS_M:
            key = f"{round(thr * 100)}cm"
            t_rec: float | None = None
            if after.any() and not fell_in_window:
                ta, ea = t[after], error[after]
                above = np.nonzero(ea >= thr)[0]
                if len(above) == 0:
                    t_rec = t1
                elif above[-1] + 1 < len(ta):
                    t_rec = float(ta[above[-1] + 1])
            res[f"recovery_time_{key}_s"] = None if t_rec is None else t_rec - t1
            res[f"recovery_steps_{key}"] = (
                None if t_rec is None else int(np.count_nonzero((touch > t1) & (touch <= t_rec)))
            )
        results[i] = res
    return results


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
    warnings = [str(w) for w in check_plan(session.plan, session.spec, config)]  # the walked plan
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


if __name__ == "__main__":
    sys.exit(main())
