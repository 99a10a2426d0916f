"""Push-recovery envelopes: ``python -m dcmviz.sweep PRESET [--sim lip|mujoco] [--directions 8]
[--push-duration 0.2] [--phase 0.5] [--out DIR] [--jobs N]``.

For each horizontal push direction (0 = +x forward, counter-clockwise) and each of three
controllers

* ``tracking``: DCM tracking only, eq. (24) (no step adjustment, no observer);
* ``step_adjustment``: step adjustment and the adapted DCM reference, eqs. (27)–(35), (40)/(41);
* ``step_adjustment+observer``: the same plus the disturbance observer, eqs. (42)–(49);

the largest push impulse J = |F| T_push (N·s) that the walk survives is found: a push of the given
duration starts at a fraction ``--phase`` of the single support of the ``--step``-th step (a
mid-walk step), and the robot keeps walking until ``--settle-steps`` step periods after the push
(or to the end of the plan with ``--full``).  Survived = not fallen by then.

Survival need not be monotone in the impulse (a larger push can trigger a different, luckier
footstep adaptation), so a coarse grid over the bracket comes first: the result is the bisected
boundary below the *first* failing grid point, and any grid point that survives above it is
reported as ``non_monotone``.

``--ramp-test`` instead bisects the held force of the preset's ramped push (tug of war) for each
controller: the smallest force at which the robot falls, to the end of ``sim.duration``.

Outputs in ``--out``: ``envelope.json``, ``envelope.csv``, ``envelope.png`` (polar plot), or
``ramp.json`` for the ramp test.  Exit 2 with a one-line reason for bad input.
"""

from __future__ import annotations

import argparse
import copy
import csv
import json
import math
import multiprocessing
import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dcmviz import GRAVITY
from dcmviz.cli import BadInput, Parser, fraction, positive_int, positive_seconds
from dcmviz.config import Config, ConfigError, load_preset
from dcmviz.gait import plan_from_config
from dcmviz.session import Session

PROG = "dcmviz.sweep"
CONTROLLERS: dict[str, dict[str, bool]] = {
    "tracking": {"step_adjustment": False, "observer": False},  # eq. (24)
    "step_adjustment": {"step_adjustment": True, "observer": False},  # eqs. (27)-(35), (40)/(41)
    "step_adjustment+observer": {"step_adjustment": True, "observer": True},  # + eqs. (42)-(49)
}


# ---------------------------------------------------------------------------------------------
# one rollout


@dataclass(frozen=True)
class Trial:
    """Everything a worker needs for the rollouts of one envelope cell (picklable)."""

    config: Config  # preset with the controller set and no pushes of its own
    backend: str
    start_s: float  # push start
    duration_s: float  # push duration
    end_s: float  # the run ends here (survived = not fallen by then)
    body: str = "torso"
    ramp_s: float = 0.0


class Rollouts:
    """Rollouts of one trial with different push forces.

    Every rollout is identical until the push starts, so the session is simulated to that instant
    once and deep-copied for each force (falls back to a fresh run if the backend cannot be copied).
    """

    def __init__(self, trial: Trial) -> None:
        self.trial = trial
        self.runs = 0
        session = Session(trial.config, backend=trial.backend)
        session.run(max(0.0, trial.start_s - session.t), stop_on_fall=True)
        try:
            self.snapshot: Session | None = copy.deepcopy(session)
        except Exception:  # noqa: BLE001 - any backend that refuses to be copied
            self.snapshot = None

    def _start(self) -> Session:
        if self.snapshot is not None:
            return copy.deepcopy(self.snapshot)
        session = Session(self.trial.config, backend=self.trial.backend)
        session.run(max(0.0, self.trial.start_s - session.t), stop_on_fall=True)
        return session

    def survives(self, force: Sequence[float]) -> bool:
        """Walk on with one push of ``force`` (N, world); True if not fallen by ``end_s``."""
        trial = self.trial
        session = self._start()
        session.push(
            force, trial.duration_s, ramp=trial.ramp_s, body=trial.body, start=trial.start_s
        )
        session.run(trial.end_s - session.t, stop_on_fall=True)
        self.runs += 1
        return not session.fell


def survives(trial: Trial, force: Sequence[float]) -> bool:
    """One rollout of ``trial`` with a push of ``force`` (N, world): True if it did not fall."""
    return Rollouts(trial).survives(force)


@dataclass
class Boundary:
    """Result of a 1-D search for the largest surviving magnitude."""

    max_ok: float  # largest magnitude known to survive (below the first failure)
    first_fail: float | None  # smallest magnitude known to fall (None: never fell in the bracket)
    non_monotone: list[float] = field(default_factory=list)  # survived above a failure
    runs: int = 0

    @property
    def capped(self) -> bool:
        return self.first_fail is None


def find_boundary(
    ok: Callable[[float], bool], hi: float, *, grid: int = 6, iterations: int = 7
) -> Boundary:
    """Coarse grid over (0, hi], then bisection below the first failing grid point.

    ``ok(0)`` is assumed true.  The result's resolution is hi / grid / 2**iterations.
    """
    points = [hi * (i + 1) / grid for i in range(grid)]
    runs = 0
    lo, fail = 0.0, None
    survived_grid: list[float] = []
    for p in points:
        runs += 1
        if ok(p):
            survived_grid.append(p)
            if fail is None:
                lo = p
        elif fail is None:
            fail = p  # keep scanning: a survivor above it shows non-monotonicity
    if fail is None:
        return Boundary(lo, None, [], runs)
    above = [p for p in survived_grid if p > fail]
    hi_b = fail
    for _ in range(iterations):
        mid = 0.5 * (lo + hi_b)
        runs += 1
        if ok(mid):
            lo = mid
        else:
            hi_b = mid
    return Boundary(lo, hi_b, above, runs)


# ---------------------------------------------------------------------------------------------
# envelope


def push_window(config: Config, step: int, phase: float) -> tuple[float, float, float]:
    """(push start, lift-off, touchdown) in s for a push at ``phase`` of step ``step``'s single
    support (``step`` 1-based, in the nominal plan)."""
    plan = plan_from_config(config)
    if not 1 <= step <= len(plan.steps):
        raise BadInput(f"--step {step}: the preset's plan has steps 1..{len(plan.steps)}")
    t_lift, t_touch = plan.swing_window(step - 1)
    return t_lift + phase * (t_touch - t_lift), t_lift, t_touch


def _cell(job: tuple[Trial, float, str, float, int, int]) -> dict[str, Any]:
    trial, direction, controller, hi, grid, iterations = job
    unit = np.array([math.cos(direction), math.sin(direction), 0.0])
    wall = time.perf_counter()
    rollouts = Rollouts(trial)
    # search over the impulse J (N·s); the force is J / T_push
    b = find_boundary(
        lambda j: rollouts.survives(unit * (j / trial.duration_s)),
        hi,
        grid=grid,
        iterations=iterations,
    )
    return {
        "direction_deg": round(math.degrees(direction), 6),
        "controller": controller,
        "max_impulse_ns": b.max_ok,
        "max_force_n": b.max_ok / trial.duration_s,
        "first_fail_impulse_ns": b.first_fail,
        "capped": b.capped,
        "non_monotone_ns": b.non_monotone,
        "runs": b.runs,
        "wall_time_s": time.perf_counter() - wall,
    }


def _pool_map(fn: Callable, jobs: list, n_jobs: int) -> list:
    if n_jobs <= 1 or len(jobs) <= 1:
        return [fn(j) for j in jobs]
    method = "fork" if "fork" in multiprocessing.get_all_start_methods() else None
    with multiprocessing.get_context(method).Pool(min(n_jobs, len(jobs))) as pool:
        return pool.map(fn, jobs, chunksize=1)


@dataclass
class SweepSettings:
    backend: str = "lip"
    directions: int = 8
    push_duration_s: float = 0.2
    phase: float = 0.5
    step: int = 4
    settle_steps: float = 3.0
    full: bool = False
    max_impulse_ns: float = 150.0
    grid: int = 6
    iterations: int = 7
    jobs: int = field(default_factory=lambda: os.cpu_count() or 1)
    body: str = "torso"
    controllers: tuple[str, ...] = tuple(CONTROLLERS)
    angles_deg: tuple[float, ...] | None = None  # explicit directions instead of ``directions``

    def direction_angles(self) -> list[float]:
        """Push directions (rad), 0 = +x forward, counter-clockwise."""
        if self.angles_deg is not None:
            return [math.radians(a) for a in self.angles_deg]
        return [2.0 * math.pi * i / self.directions for i in range(self.directions)]


def envelope(config: Config, settings: SweepSettings) -> dict[str, Any]:
    """The push-recovery envelope of a preset: one row per (direction, controller)."""
    base = config.replace(pushes=[])
    start, t_lift, t_touch = push_window(base, settings.step, settings.phase)
    push_end = start + settings.push_duration_s
    plan = plan_from_config(base)
    period = base.gait.t_ss + base.gait.t_ds
    if settings.full:
        end = plan.t_end + base.gait.t_stop
    else:
        end = push_end + settings.settle_steps * period
    jobs = []
    for name in settings.controllers:
        cfg = base.replace(control={**base.control.model_dump(), **CONTROLLERS[name]})
        trial = Trial(cfg, settings.backend, start, settings.push_duration_s, end, settings.body)
        for direction in settings.direction_angles():
            jobs.append(
                (
                    trial,
                    direction,
                    name,
                    settings.max_impulse_ns,
                    settings.grid,
                    settings.iterations,
                )
            )
    wall = time.perf_counter()
    rows = _pool_map(_cell, jobs, settings.jobs)
    wall = time.perf_counter() - wall
    rows.sort(key=lambda r: (r["direction_deg"], settings.controllers.index(r["controller"])))
    return {
        "preset": config.name,
        "robot": config.robot.model,
        "backend": settings.backend,
        "settings": asdict(settings),
        "push_start_s": start,
        "swing_side": plan.steps[settings.step - 1].side,
        "single_support_s": [t_lift, t_touch],
        "run_end_s": end,
        "resolution_ns": settings.max_impulse_ns / settings.grid / 2**settings.iterations,
        "wall_time_s": wall,
        "rows": rows,
        "ratios": ratios(rows),
    }


def ratios(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per direction: each controller's max impulse over tracking's."""
    by_dir: dict[float, dict[str, float]] = {}
    for r in rows:
        by_dir.setdefault(r["direction_deg"], {})[r["controller"]] = r["max_impulse_ns"]
    out = []
    for d in sorted(by_dir):
        row: dict[str, Any] = {"direction_deg": d}
        base = by_dir[d].get("tracking")
        for name, value in by_dir[d].items():
            if name != "tracking":
                row[f"{name}/tracking"] = value / base if base else None
        out.append(row)
    return out


def table(result: dict[str, Any]) -> str:
    """The envelope as a text table (impulses in N·s) with ratios to tracking."""
    names = result["settings"]["controllers"]
    rows = result["rows"]
    by_dir: dict[float, dict[str, dict]] = {}
    for r in rows:
        by_dir.setdefault(r["direction_deg"], {})[r["controller"]] = r
    head = f"{'dir °':>6} " + " ".join(f"{n:>25}" for n in names)
    ratio_names = [n for n in names if n != "tracking" and "tracking" in names]
    head += "".join(f" {n + '/trk':>28}" for n in ratio_names)
    lines = [
        f"max survived push impulse (N·s), {result['settings']['push_duration_s']} s pushes at "
        f"{result['push_start_s']:.3f} s ({result['settings']['phase']:.2f} of step "
        f"{result['settings']['step']}'s single support, {result['swing_side']} foot swinging), "
        "resolution "
        f"{result['resolution_ns']:.2f} N·s",
        head,
    ]
    for d in sorted(by_dir):
        cells = []
        for n in names:
            r = by_dir[d].get(n)
            mark = ("≥" if r["capped"] else "") + ("*" if r["non_monotone_ns"] else "")
            cells.append(f"{mark}{r['max_impulse_ns']:7.1f} ({r['max_force_n']:6.0f} N)".rjust(25))
        line = f"{d:6.1f} " + " ".join(cells)
        base = by_dir[d]["tracking"]["max_impulse_ns"] if "tracking" in names else None
        for n in ratio_names:
            v = by_dir[d][n]["max_impulse_ns"]
            line += f" {(v / base if base else float('nan')):28.2f}"
        lines.append(line)
    if any(r["non_monotone_ns"] for r in rows):
        lines.append("* survival is not monotone here: a larger grid impulse survived (see JSON)")
    if any(r["capped"] for r in rows):
        lines.append("≥ survived the whole bracket; raise --max-impulse")
    lines.append(f"{len(rows)} cells in {result['wall_time_s']:.1f} s wall")
    return "\n".join(lines)


def write_envelope(result: dict[str, Any], out: Path) -> list[Path]:
    """envelope.json, envelope.csv and the polar plot envelope.png in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "envelope.json", out / "envelope.csv", out / "envelope.png"]
    paths[0].write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    with paths[1].open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["direction_deg", "controller", "max_impulse_ns", "max_force_n", "capped"])
        for r in result["rows"]:
            w.writerow(
                [
                    r["direction_deg"],
                    r["controller"],
                    f"{r['max_impulse_ns']:.3f}",
                    f"{r['max_force_n']:.2f}",
                    r["capped"],
                ]
            )
    plot_polar(result, paths[2])
    return paths


def plot_polar(result: dict[str, Any], path: Path) -> None:
    """One closed curve per controller: max impulse (N·s) against push direction."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(6.4, 6.4))
    ax = fig.add_subplot(projection="polar")
    styles = {"tracking": "o-", "step_adjustment": "s-", "step_adjustment+observer": "^--"}
    for name in result["settings"]["controllers"]:
        rows = sorted(
            (r for r in result["rows"] if r["controller"] == name),
            key=lambda r: r["direction_deg"],
        )
        theta = np.radians([r["direction_deg"] for r in rows])
        radius = np.array([r["max_impulse_ns"] for r in rows])
        theta, radius = np.append(theta, theta[:1]), np.append(radius, radius[:1])
        ax.plot(theta, radius, styles.get(name, "-"), label=name, lw=1.8, ms=5)
    ax.set_theta_zero_location("E")  # 0° = +x forward, counter-clockwise = toward +y (left)
    ax.set_title(
        f"{result['preset']} ({result['robot']}, {result['backend']}): max push impulse (N·s)\n"
        f"{result['settings']['push_duration_s']} s push at "
        f"{result['settings']['phase']:.0%} of step {result['settings']['step']}'s single "
        f"support ({result['swing_side']} foot swinging); 0° = forward, 90° = left",
        fontsize=9,
    )
    ax.legend(loc="lower left", bbox_to_anchor=(-0.12, -0.12), fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
# ramp (tug of war) test


def _ramp_cell(job: tuple[Trial, np.ndarray, str, float, int, int]) -> dict[str, Any]:
    trial, unit, controller, hi, grid, iterations = job
    wall = time.perf_counter()
    rollouts = Rollouts(trial)
    b = find_boundary(lambda f: rollouts.survives(unit * f), hi, grid=grid, iterations=iterations)
    return {
        "controller": controller,
        "max_held_force_n": b.max_ok,
        "first_fall_force_n": b.first_fail,
        "capped": b.capped,
        "non_monotone_n": b.non_monotone,
        "runs": b.runs,
        "wall_time_s": time.perf_counter() - wall,
    }


def ramp_test(config: Config, settings: SweepSettings, *, max_force_n: float) -> dict[str, Any]:
    """Bisect the held force of the preset's (first) ramped push for each controller."""
    ramped = [p for p in config.pushes if p.ramp > 0.0]
    if not ramped:
        raise BadInput("--ramp-test: the preset has no ramped push (pushes[*].ramp > 0)")
    push = ramped[0]
    force = np.array(push.force, dtype=float)
    unit = force / np.linalg.norm(force)
    base = config.replace(pushes=[])
    session = Session(base, backend=settings.backend)
    mass = float(session.backend.mass)
    jobs = []
    for name in settings.controllers:
        cfg = base.replace(control={**base.control.model_dump(), **CONTROLLERS[name]})
        trial = Trial(
            cfg,
            settings.backend,
            push.start,
            push.duration,
            config.sim.duration,
            push.body,
            push.ramp,
        )
        jobs.append((trial, unit, name, max_force_n, settings.grid, settings.iterations))
    wall = time.perf_counter()
    rows = _pool_map(_ramp_cell, jobs, settings.jobs)
    for r in rows:
        r["max_held_force_pct_weight"] = 100.0 * r["max_held_force_n"] / (mass * GRAVITY)
    return {
        "preset": config.name,
        "robot": config.robot.model,
        "backend": settings.backend,
        "mass_kg": mass,
        "push": push.model_dump(),
        "preset_force_n": float(np.linalg.norm(force)),
        "run_end_s": config.sim.duration,
        "resolution_n": max_force_n / settings.grid / 2**settings.iterations,
        "wall_time_s": time.perf_counter() - wall,
        "rows": rows,
    }


def ramp_table(result: dict[str, Any]) -> str:
    p = result["push"]
    lines = [
        f"ramped push ({p['ramp']} s ramp, held to {p['start'] + p['duration']:.1f} s, "
        f"direction {np.round(np.array(p['force']) / result['preset_force_n'], 3).tolist()}); "
        f"preset force {result['preset_force_n']:.0f} N "
        f"({100 * result['preset_force_n'] / (result['mass_kg'] * GRAVITY):.1f} % of weight)",
        f"{'controller':>26} {'max held force':>16} {'% weight':>9} {'falls at':>10}",
    ]
    for r in result["rows"]:
        fail = r["first_fall_force_n"]
        held = ("≥" if r["capped"] else "") + f"{r['max_held_force_n']:.1f} N"
        lines.append(
            f"{r['controller']:>26} {held:>16}"
            f" {r['max_held_force_pct_weight']:8.1f}% "
            + (f"{fail:9.1f} N" if fail is not None else "     never")
            + (" (non-monotone)" if r["non_monotone_n"] else "")
        )
    lines.append(f"in {result['wall_time_s']:.1f} s wall")
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------
# CLI


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
