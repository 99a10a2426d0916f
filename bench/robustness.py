"""Survival of the paper's push and tug of war on one robot, at several scales (issue 22).

    python bench/robustness.py --robot NAME|PATH [--jobs N] [--json PATH] [--sim mujoco|lip]
        [--scales 0.5,1,1.5,2,2.5,3] [--starts 4] [--levels 5,10,15,20,25,30,35]
        [--pull-sides +,-] [--recovery next_step[,multi_step,...]] [--no-observer]
        [--only push|pull] [--ceiling]

Both scenarios are scaled by the robot's mass m and walk a gait derived from the robot's own
numbers (``walking_config``), never tuned per robot:

- push (paper, Sec. IV): +F then -F lateral, 1 s each, 4 s apart, on the torso, with
  F = scale × 25 N × m / 76 kg (Toro's 76 kg: the same acceleration, 0.33 m/s² per unit scale).
  The first push starts at 2.5 s plus an offset that sweeps one gait cycle (two steps) in
  ``--starts`` equal parts, so it lands in every phase of the gait and on either stance foot.
- pull (paper's observer test): a lateral force on the torso ramped from 0 over 6 s from t = 1 s
  and held to the end (walking 12 steps, then standing), level × m g, on each side asked.

``--sim lip`` runs the same walker on the point mass with the robot's mass, CoM height, feet and
reach (the ceiling of what the paper's controller does with those numbers; the humanoid in
MuJoCo, the default, is what a user sees).  ``--lever`` (with ``--sim lip``) scales its forces by
(z + h)/z, z the CoM height and h the torso's height above the CoM (``Robot.push_lever_m``):
pushed at the torso, a humanoid whose feet counter the push's moment (no change of angular
momentum) has its CoM accelerated as the point mass by F (z + h)/z (the moment about the CoM,
h F, moves the CoP by h F/(m g) for the same ground force), so this is the ceiling of the paper's
controller for the torso push without angular momentum (``lever_factor``).  ``--ceiling`` (with
MuJoCo) runs the pushes three ways in one go, the humanoid, the lever-loaded point mass and the
point mass pushed at its CoM, prints the starts each survives per scale side by side and says,
per scale where the humanoid falls, what the shortfall comes to (``ceiling_verdicts``): the
robot's own numbers (the point mass at its CoM falls too), the torso push's moment (only the
lever-loaded point mass falls: angular momentum to take), or the whole-body layer (JSON
``ceiling``: scales, starts, lever_factor, and the survived starts per scale of humanoid, lever,
com).  It answers "it falls on my robot" with where to look.

``--recovery`` with several strategies (comma-separated) runs the whole bench once per strategy
and then compares them in one table (``compare_strategies``): per strategy the starts survived
at each push scale and the first fall of each pull side, and, where ``next_step`` (the paper's)
is among them, which strategy falls earlier than it (issue 22: every strategy at least as
robust as ``next_step``).  The JSON is then ``{"strategies": {name: the single run's JSON},
"comparison": ...}``.

Per start time (push) and per side (pull) it prints which levels were survived, the first
fall, and the holes: levels that fell although a higher level of the same row was survived
(survival should be monotone in the force).  Under the push table, per start, the scale beyond
which no footsteps save the walk (``push_bounds``, JSON ``push.bounds``: with the torso's moment
at the feet or taken by the trunk; for legs that reach across, also with the feet kept apart),
and per scale at how many starts it lies beyond: a fall there is physics, not a controller.
The same four under the walker's swings (``swing_*``: the CoP only under the feet that stand,
single supports of ``timing.MIN_SS_S`` at least and swings no faster than the robot's
``max_swing_speed_m_s``; ``dcmviz.sweep.bounds.swing_bound_at``): beyond those, no walk of this
walker's catches ξ; per scale, how many of the starts that fell lie beyond them for the
strategy's legs (JSON ``push.falls_beyond_swing_bound``).
With MuJoCo it also walks the gait once unpushed and names the joints nearest their torque
limits in single support (``torque_headroom``: a robot whose knees are at their limit walking
has none left for a push).  After the pull table
it prints how hard the legs can lean against a pull on one foot (``lean_bounds``, statics:
:mod:`dcmviz.robots.lean`), with the trunk upright and rolled.  ``--json`` writes the same as data
(``torque_headroom``: joint, limit_nm, at_limit_share, peak_share; ``lean``: trunk_roll_rad,
pull_pct, com_outboard_m, binding).  Under the push table it names the falls that came more than
a second after a push had ended (``late_falls``, JSON ``push.late_falls``): the walk did not
settle after a push it had caught, which is the whole-body layer's, not a capture limit.
With MuJoCo each rollout counts, from the push (or the pull) on, the ticks with a joint's torque
at ≥ AT_LIMIT of its limit (JSON ``torque_limits`` per rollout): each row's first fall is told
with that share, the same over its last FINAL_S and the joints there most often
(``first_fall_torque_limits``).  A share that is high from the push on says the actuators, which
the point mass does not model, were saturated all through the recovery (Romeo at 2x: 67-78 %,
its knees at 38 N m); high only at the end, it may be the fall's symptom, not its cause (Talos's
2x falls, 65 % of their last 0.5 s at the stance hip roll's 160 N m, come at the same times
with every torque limit raised by half).  A copy of the robot file with ``[actuators]
torque_scale = 1.5`` tells which: Romeo's 15 % pull falls then hold up to 20 %.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dcmviz import GRAVITY  # noqa: E402
from dcmviz.config import Config, Push  # noqa: E402
from dcmviz.recovery import STRATEGIES  # noqa: E402
from dcmviz.robots import load_robot  # noqa: E402
from dcmviz.run import load_config  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BASE_PRESET = ROOT / "presets" / "walk_forward.toml"
PAPER_FORCE_N = 25.0  # the paper's lateral push on Toro
PAPER_MASS_KG = 76.0  # Toro
PUSH_S = 1.0
PUSH_FIRST_S = 2.5  # first push start before the offset
PUSH_GAP_S = 4.0  # -F this long after +F
PULL_START_S = 1.0
PULL_RAMP_S = 6.0
N_STEPS = 12
PUSH_DURATION_S = 13.5  # the last push ends by 8.85 s; the walk ends at 12.8 s
PULL_DURATION_S = 14.0  # as presets/tug_of_war.toml: walking ends at 12.8 s, then standing
DEFAULT_SCALES = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)
DEFAULT_LEVELS = (5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0)  # % of m g
# --repeats: repeat k of a rollout has its push or pull × (1 + k·REPEAT_STEP), far below anything
# physical; next to a first fall the outcome can still change (the walk is chaotic there), and a
# cell that does reads "k/N survived" instead of one outcome that another machine may not repeat
REPEAT_STEP = 1e-6


def walking_config(
    robot: str, preset: str | Path = BASE_PRESET, overrides=(), sim: str = "mujoco"
) -> Config:
    """``preset`` on ``robot`` with the gait derived from the robot's numbers: steps of
    min(0.20 m, 0.8 × max_step_length), width = the standing foot spacing, b from the standing
    CoM height (inside the robot's b range), adjustment up to min(0.3 m, max_step_length),
    N_STEPS steps (the preset's timing, observer, recovery)."""
    spec = load_robot(robot).spec
    b_lo, b_hi = spec.b_range_s
    b = min(max(spec.b_nominal_s, b_lo), b_hi)
    sets = [
        f'robot.model="{robot}"',
        f"gait.step_length={round(min(0.20, 0.8 * spec.max_step_length_m), 3)}",
        f"gait.step_width={round(spec.foot_spacing_m, 3)}",
        f"gait.n_steps={N_STEPS}",
        f"dcm.b={b!r}",
        f"control.max_step_adjustment={round(min(0.3, spec.max_step_length_m), 3)}",
        f'sim.backend="{sim}"',
    ]
    config = load_config(str(preset), [*sets, *overrides])
    return config.model_copy(update={"pushes": []})


def lever_factor(robot: str, body: str = "torso") -> float:
    """(z + h)/z: a push on ``body``, h above the CoM (standing), loads the CoP as a push at the
    CoM (z above the soles) this many times stronger when the feet counter its moment h F: the
    ground's moment about the CoM, (p − c) m g + z f = h F, gives m c̈ = F (z + h)/z − m g (p − c)/z
    (lateral, f the ground's horizontal force, F the push)."""
    r = load_robot(robot)
    z = r.spec.com_height_m
    return (z + r.push_lever_m(body)) / z


def push_config(
    base: Config, mass: float, scale: float, start: float, factor: float = 1.0
) -> Config:
    f = scale * factor * PAPER_FORCE_N * mass / PAPER_MASS_KG
    pushes = [
        Push(start=start, duration=PUSH_S, force=(0.0, f, 0.0), ramp=0.0, body="torso"),
        Push(start=start + PUSH_GAP_S, duration=PUSH_S, force=(0.0, -f, 0.0), ramp=0.0,
             body="torso"),
    ]  # fmt: skip
    return base.model_copy(update={"pushes": pushes})


def pull_config(
    base: Config, mass: float, level_pct: float, side: float, factor: float = 1.0
) -> Config:
    f = side * factor * level_pct / 100.0 * mass * GRAVITY
    push = Push(
        start=PULL_START_S,
        duration=PULL_DURATION_S,
        force=(0.0, f, 0.0),
        ramp=PULL_RAMP_S,
        body="torso",
    )
    return base.model_copy(update={"pushes": [push]})


@dataclass(frozen=True)
class Job:
    kind: str  # "push" | "pull"
    row: str  # start offset (push) or side (pull)
    level: float  # scale (push) or % of m g (pull)
    config: Config
    duration: float
    gains: tuple[tuple[str, float], ...] = ()
    repeat: int = 0  # k of --repeats: the load × (1 + k·REPEAT_STEP)


def _with_gains(gains: tuple[tuple[str, float], ...]) -> None:
    """Experiments: whole-body QP gains (``Gains`` fields) on top of the robot's, this process."""
    if not gains:
        return
    from dcmviz.robots import gains as module

    base = module.Gains.__dict__["for_robot"].__func__

    def for_robot(cls, robot):
        g = base(cls, robot)
        for key, value in gains:
            setattr(g, key, value)
        return g

    module.Gains.for_robot = classmethod(for_robot)


_PREFIX: dict[str, Any] = {}  # this process's walk to the first push: key -> SessionState


def _session(job: Job):
    """A session for ``job``: for a push, the walk to its first push is the same for every force,
    so it is walked once per process (the push jobs of one start come in one chunk) and each job
    continues from its state (``Session.from_state``, bit for bit) with its pushes scheduled."""
    from dcmviz.session import Session

    start = min(p.start for p in job.config.pushes)
    if job.kind == "pull":
        return Session(job.config, backend=job.config.sim.backend)
    walk = job.config.model_copy(update={"pushes": ()})
    key = walk.model_dump_json() + f"{start!r}{job.gains}"
    state = _PREFIX.get(key)
    if state is None:
        session = Session(walk, backend=walk.sim.backend)
        session.run(start - session.t, stop_on_fall=True)  # every tick before the push starts
        _PREFIX.clear()  # one prefix kept: the jobs come ordered by start
        state = _PREFIX[key] = session.save_state()
    session = Session.from_state(state)
    for p in job.config.pushes:
        session.push(p.force, p.duration, ramp=p.ramp, body=p.body, start=p.start)
    return session


FINAL_S = 0.5  # s before a fall whose torque limits are told apart


def _run_counting_torque_limits(session, job: Job) -> dict[str, Any] | None:
    """Run ``session`` to the job's end (or its fall) and, on the humanoid, count from the load's
    start (the first push's, or the pull's) the ticks in which the whole-body QP's torque is at a
    joint's limit (≥ AT_LIMIT of it): ``share`` of those ticks with any joint there, the same
    over the last FINAL_S before the end (``final_share``: a fall at the actuators' limits reads
    1.0) with the ``final_joints`` there most often, and the ``joints`` at their limit most often
    from the load's start, each with its share.  None on the point mass, which has no joints."""
    end = job.duration
    if job.config.sim.backend != "mujoco":
        session.run(end - session.t, stop_on_fall=True)
        return None
    start = min(p.start for p in job.config.pushes)  # the first push's, or the pull's
    robot = session.backend.robot
    limit, names = AT_LIMIT * robot.torque_limit, robot.model.joint_names
    rows: list[np.ndarray] = []  # per tick from the load's start: which joints are at the limit
    while session.t < end - 1e-9:
        session.step()
        if session.t >= start:
            rows.append(np.abs(session.backend.wbc.last.tau) >= limit)
        if session.metrics.fell:
            break
    if not rows:
        return {"share": 0.0, "final_share": 0.0, "final_joints": [], "joints": []}
    at = np.array(rows)
    final = at[-max(1, round(FINAL_S / session.backend.control_dt)) :]

    def busiest(shares: np.ndarray) -> list[list]:
        return [[names[i], float(shares[i])] for i in np.argsort(-shares, kind="stable")[:3]
                if shares[i] > 0]  # fmt: skip

    return {
        "share": float(at.any(axis=1).mean()),
        "final_share": float(final.any(axis=1).mean()),
        "final_joints": busiest(final.mean(axis=0)),
        "joints": busiest(at.mean(axis=0)),
    }


def rollout(job: Job) -> dict[str, Any]:
    _with_gains(job.gains)
    t0 = time.perf_counter()
    session = _session(job)
    limits = _run_counting_torque_limits(session, job)
    metrics = session.metrics
    return {
        "kind": job.kind,
        "row": job.row,
        "level": job.level,
        "force_n": float(max(abs(p.force[1]) for p in job.config.pushes)),
        "start_s": float(min(p.start for p in job.config.pushes)),  # the first push's
        "fell": bool(metrics.fell),
        "fall_time_s": metrics.fall_time_s,
        "repeat": job.repeat,
        "steps_completed": int(session.steps_completed),
        "max_dcm_error_m": float(metrics.max_dcm_error_m),
        "torque_limits": limits,
        "wall_s": time.perf_counter() - t0,
    }


LEAN_ROLLS = (0.0, 0.15, 0.3)  # rad: the trunk upright, and rolled away from the pull


def lean_bounds(robot: str) -> list[dict]:
    """:func:`dcmviz.robots.lean.lean_reach` on the right foot (a pull towards +y; the robots are
    symmetric) with the trunk upright and rolled by LEAN_ROLLS: the largest sustained torso pull
    (% of m g) its legs hold on one foot, and the joints at the end of their range."""
    from dcmviz.robots.lean import lean_reach

    rows = []
    for roll in LEAN_ROLLS:
        lean = lean_reach(load_robot(robot), roll, "right")
        rows.append({"trunk_roll_rad": lean.trunk_roll_rad, "pull_pct": 100 * lean.pull_fraction,
                     "com_outboard_m": lean.com_outboard_m, "binding": list(lean.binding)})  # fmt: skip
    return rows


AT_LIMIT = 0.98  # |τ| at least this share of a joint's torque limit counts as at the limit


def torque_headroom(config: Config, gains: tuple[tuple[str, float], ...] = ()) -> list[dict]:
    """The walk of ``config`` in MuJoCo without pushes or pulls: per actuated joint, the share
    of single-support ticks in which the whole-body QP's torque is at the joint's limit
    (≥ AT_LIMIT of it) and its peak |τ|/limit, the busiest joints first.  A joint at its limit
    while the robot walks unpushed leaves nothing for a push or a pull (Romeo's stance knees:
    15–16 % of single support; Talos and the G1: none)."""
    from dcmviz.session import Session

    _with_gains(gains)
    session = Session(config.model_copy(update={"pushes": []}), backend="mujoco")
    robot = session.backend.robot
    names = robot.model.joint_names  # the actuated joints, Pinocchio's order (as τ)
    limit = robot.torque_limit
    share = []
    while session.t < PUSH_DURATION_S and not session.fell:
        command = session.step()
        if command.swing_side is not None:  # single support: one leg holds the robot
            share.append(np.abs(session.backend.wbc.last.tau) / limit)
    a = np.array(share).reshape(-1, len(names))
    at_limit = (a >= AT_LIMIT).mean(axis=0) if len(a) else np.zeros(len(names))
    peak = a.max(axis=0) if len(a) else np.zeros(len(names))
    order = np.lexsort((-peak, -at_limit))
    return [
        {"joint": names[i], "limit_nm": float(limit[i]), "at_limit_share": float(at_limit[i]),
         "peak_share": float(peak[i])}
        for i in order
    ]  # fmt: skip


class _Serial:
    """``map`` in this process (``--jobs 1``), lazily."""

    def __enter__(self) -> _Serial:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    @staticmethod
    def map(fn, items, chunksize: int = 1):
        return map(fn, items)


def summarise(results: list[dict[str, Any]], levels: list[float]) -> dict[str, Any]:
    """Per row: survived levels, first fall, holes (falls below a survived level).  With
    repeats (--repeats) a level counts as survived only if every repeat survived and as a fall
    if any fell (``survived_share``: the share that survived; ``fall_time_s``: the earliest)."""
    rows: dict[str, dict[float, list[dict[str, Any]]]] = {}
    for r in results:
        rows.setdefault(r["row"], {}).setdefault(r["level"], []).append(r)
    out = {}
    for row, by_level in rows.items():
        runs = {lv: by_level[lv] for lv in levels if lv in by_level}
        share = {lv: sum(not r["fell"] for r in rs) / len(rs) for lv, rs in runs.items()}
        fell = {lv: share[lv] < 1.0 for lv in runs}
        survived = [lv for lv, f in fell.items() if not f]
        falls = [lv for lv, f in fell.items() if f]
        highest = max(survived) if survived else None
        holes = [lv for lv in falls if highest is not None and lv < highest]
        out[row] = {
            "first_fall": min(falls) if falls else None,
            "highest_survived": highest,
            "holes": holes,
            "fell": {str(k): v for k, v in fell.items()},
            "fall_time_s": {
                str(lv): min((r["fall_time_s"] for r in rs if r["fell"]), default=None)
                for lv, rs in runs.items()
            },  # fmt: skip
            "survived_share": {str(lv): share[lv] for lv in runs},
            "repeats": {str(lv): len(rs) for lv, rs in runs.items()},
        }
    return out


def table(title: str, unit: str, summary: dict[str, Any], levels: list[float]) -> str:
    head = f"{title:<14}" + "".join(f"{lv:>7g}" for lv in levels) + "   first fall  holes"
    lines = [head, "-" * len(head)]
    for row, s in summary.items():
        cells = []
        for lv in levels:
            f = s["fell"].get(str(lv))
            if f is None:
                cells.append(f"{'':>7}")
            elif f and s["survived_share"][str(lv)]:  # some repeats survived, some fell
                share, n = s["survived_share"][str(lv)], s["repeats"][str(lv)]
                cells.append(f"{f'{round(share * n)}/{n}':>7}")
            elif f:
                cells.append(f"{'F' + format(s['fall_time_s'][str(lv)], '.1f'):>7}")
            else:
                cells.append(f"{'ok':>7}")
        first = "-" if s["first_fall"] is None else f"{s['first_fall']:g}{unit}"
        holes = ",".join(f"{h:g}" for h in s["holes"]) or "-"
        lines.append(f"{row:<14}" + "".join(cells) + f"   {first:>10}  {holes}")
    return "\n".join(lines)


SETTLE_S = 1.0  # a fall later than this after a push ended: the walk did not settle


def late_falls(results: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Push rollouts that fell more than SETTLE_S after a push had ended (``after_push_s``; the
    second push may have begun meanwhile: ``into_next_s``, else None): not a push the robot
    could not catch when it came, but a walk that did not settle after it (an oscillation that
    grew, a slow drift), which a push arriving then may only finish off."""
    out = []
    for r in results:
        if not r["fell"]:
            continue
        first = r["start_s"]
        t = r["fall_time_s"]
        starts = (first, first + PUSH_GAP_S)
        ended = [k for k, s in enumerate(starts) if s + PUSH_S <= t]
        if not ended or t <= starts[ended[-1]] + PUSH_S + SETTLE_S:
            continue
        k = ended[-1]
        into = t - starts[k + 1] if k + 1 < len(starts) and starts[k + 1] <= t else None
        out.append({"row": r["row"], "level": r["level"], "fall_time_s": t,
                    "after_push_s": t - starts[k] - PUSH_S, "push": ("first", "second")[k],
                    "into_next_s": into})  # fmt: skip
    return sorted(out, key=lambda x: (x["row"], x["level"]))


def first_fall_torque_limits(results: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Each row's first fall (its lowest level that fell) on the humanoid, with its torque limits
    (:func:`_run_counting_torque_limits`)."""
    out = []
    for row in dict.fromkeys(r["row"] for r in results):
        falls = sorted((r for r in results if r["row"] == row and r["fell"]
                        and r.get("torque_limits") is not None), key=lambda r: r["level"])  # fmt: skip
        if not falls:
            continue
        r = falls[0]
        lim = r["torque_limits"]
        out.append({"row": row, "level": r["level"], "fall_time_s": r["fall_time_s"], **lim})
    return out


def print_first_fall_torque_limits(
    results: list[dict[str, Any]], load: str
) -> list[dict[str, Any]]:
    """Print :func:`first_fall_torque_limits` under a table (none on the point mass); returns it."""
    limits = first_fall_torque_limits(results)
    if limits:
        print(f"  each row's first fall: the share of ticks from the {load} with a joint's torque"
              f" at ≥ {AT_LIMIT:.0%} of its limit; the same in the last {FINAL_S:g} s; the joints"
              f" there most often from the {load}:")  # fmt: skip
    unit = "x" if load == "push" else " %"
    for x in limits:
        joints = ", ".join(f"{j} {sh:.0%}" for j, sh in x["joints"]) or "-"
        print(
            f"  {x['row']}, {x['level']:g}{unit} (fell at {x['fall_time_s']:.2f} s): "
            f"{x['share']:.0%}; {x['final_share']:.0%} ({joints})"
        )
    return limits


CEILING_ROWS = (
    ("humanoid", "the humanoid (MuJoCo)"),
    ("lever", "point mass, torso lever"),
    ("com", "point mass, at the CoM"),
)


def survived_counts(results: list[dict[str, Any]], scales: list[float]) -> list[int]:
    """Per scale, how many push rollouts (one per start time) were survived; with --repeats a
    start counts once, as survived only if every repeat survived."""
    starts: dict[tuple, bool] = {}
    for r in results:
        key = (r.get("row", id(r)), r["level"])
        starts[key] = starts.get(key, True) and not r["fell"]
    return [sum(1 for (_, lv), ok in starts.items() if lv == sc and ok) for sc in scales]


def ceiling_verdicts(scales: list[float], starts: int, counts: dict[str, list[int]]) -> list[str]:
    """Per scale where the humanoid falls at some start, which of three things it comes to
    (``counts``: survived starts per scale for "humanoid", "lever" and "com"):

    - the paper's controller on the point mass with this robot's numbers falls too, pushed at
      its CoM: the robot's feet, CoM height and reach (no whole-body layer does better);
    - the point mass falls only with the torso push's moment loaded on its CoP (``--lever``):
      what the humanoid would gain by taking that moment as angular momentum (issue 22, item 4);
    - the lever-loaded point mass survives more starts than the humanoid: the whole-body layer.
    """
    lines = []
    for i, sc in enumerate(scales):
        h, lever, com = (counts[k][i] for k in ("humanoid", "lever", "com"))
        if h == starts:
            continue
        if com < starts:
            cause = (f"the point mass at its CoM falls too ({com}/{starts}): the robot's feet, CoM "
                     "height and reach under the paper's controller")  # fmt: skip
            ref = com
        elif lever < starts:
            cause = (f"the point mass holds it at its CoM ({com}/{starts}), not with the torso's "
                     f"moment at its feet ({lever}/{starts}): angular momentum to take")  # fmt: skip
            ref = lever
        else:
            cause = (f"the point mass holds it even with the torso's moment at its feet "
                     f"({lever}/{starts}): the whole-body layer")  # fmt: skip
            ref = lever
        n = abs(h - ref)
        starts_word = f"{n} start{'s' if n > 1 else ''}"
        if h < ref:
            cause += f"; the humanoid survives {starts_word} fewer"
        elif h > ref:
            cause += f"; the humanoid survives {starts_word} more (its trunk or arms take some)"
        lines.append(f"  {sc:g}x: the humanoid {h}/{starts}; {cause}")
    return lines


BOUND_KINDS = (  # key, crossing, moment_at_feet: what each of push_bounds' numbers assumes
    ("torso", True, True),  # any footsteps; the torso push's moment taken by the feet
    ("com", True, False),  # ... taken as angular momentum (the point mass pushed at its CoM)
    ("uncrossed_torso", False, True),  # the feet kept the minimum step width apart
    ("uncrossed_com", False, False),
)
SWING = "swing_"  # the same four with the walker's swings (dcmviz.sweep.bounds.swing_bound_at)


def push_bounds(config: Config, start: float) -> dict[str, Any]:
    """What the paper's push pair starting at ``start`` can be at most, in its scale (units of
    PAPER_FORCE_N m / PAPER_MASS_KG), for each push (``first``: +y at ``start``, ``second``: −y
    PUSH_GAP_S later) and over both (the smaller): the force beyond which no footsteps save the
    walk (:func:`dcmviz.sweep.bounds.footstep_bound_at`: the CoP on the pushed sole's outer edge,
    the other foot down as early as it may, as far across as the legs reach), with the torso's
    moment at the feet (``torso``) or taken by the trunk (``com``: the point mass at its CoM),
    and with the feet kept the minimum step width apart (``uncrossed_*``: every strategy but
    ``crossover``).  None where no bound applies (the pushed foot swings or may still lift).  ξ
    is read off the nominal plan: the second push's bound assumes the walk is back on it."""
    from dcmviz.sweep.bounds import footstep_bound_at, swing_bound_at

    robot = load_robot(config.robot.model)
    unit = PAPER_FORCE_N * robot.spec.mass_kg / PAPER_MASS_KG * PUSH_S
    legs_cross = bool(robot.crossover.polygons)  # without a region: crossed = uncrossed
    out: dict[str, Any] = {}
    keys = [k for k, _, _ in BOUND_KINDS] + [SWING + k for k, _, _ in BOUND_KINDS]
    for name, t, angle in (("first", start, np.pi / 2), ("second", start + PUSH_GAP_S, -np.pi / 2)):
        out[name] = {}
        found: dict[tuple, float | None] = {}  # each bound computed once
        for bound, prefix in ((footstep_bound_at, ""), (swing_bound_at, SWING)):
            for key, crossing, at_feet in BOUND_KINDS:
                asked = (bound, at_feet, crossing and legs_cross)
                if asked not in found:
                    found[asked] = bound(config, t, PUSH_S, angle, backend="mujoco",
                                         moment_at_feet=at_feet, crossing=asked[2])  # fmt: skip
                j = found[asked]
                out[name][prefix + key] = None if j is None else j / unit
    for key in keys:
        values = [out[n][key] for n in ("first", "second") if out[n][key] is not None]
        out[key] = min(values) if values else None
    return out


def bound_lines(rows: list[str], bounds: list[dict[str, Any]], scales: list[float]) -> list[str]:
    """The push table's bounds, one line per start (the crossed ones where the legs can cross;
    with the walker's swings after them where ``bounds`` has them, ``swing_*``), then per scale
    the starts it lies beyond."""
    crossing = any(b["torso"] != b["uncrossed_torso"] for b in bounds)
    swings = all(SWING + "torso" in b for b in bounds)

    def cell(x: float | None) -> str:
        return "-" if x is None else f"{x:.2f}x"

    def beyond(key: str, sc: float) -> int:
        return sum(1 for b in bounds if b[key] is not None and b[key] < sc)

    def pair(b: dict[str, Any], prefix: str) -> str:
        text = f"{cell(b[prefix + 'torso'])} / {cell(b[prefix + 'com'])}"
        if crossing:
            text += (f"; uncrossed {cell(b[prefix + 'uncrossed_torso'])} / "
                     f"{cell(b[prefix + 'uncrossed_com'])}")  # fmt: skip
        return text

    lines = []
    for row, b in zip(rows, bounds, strict=True):
        text = f"  {row}: {pair(b, '')}"
        if swings:
            text += f"  | walker's swings {pair(b, SWING)}"
        lines.append(text)
    what = (("", "every footstep"), (SWING, "every walk with the walker's swings"))
    keys = ("torso", "com", "uncrossed_torso", "uncrossed_com")[: 4 if crossing else 2]
    for sc in scales:
        for prefix, name in what[: 2 if swings else 1]:
            n = {k: beyond(prefix + k, sc) for k in keys}
            if not any(n.values()):
                continue
            text = (f"  {sc:g}x is beyond {name} at {n['torso']} of {len(rows)} starts with "
                    f"the torso's moment at the feet, at {n['com']} even with it taken by the "
                    f"trunk")  # fmt: skip
            if crossing:
                text += (f"; without crossing the legs at {n['uncrossed_torso']} and "
                         f"{n['uncrossed_com']}")  # fmt: skip
            lines.append(text)
    return lines


def falls_beyond(
    summary: dict[str, Any],
    rows: list[str],
    bounds: list[dict[str, Any]],
    scales: list[float],
    crossing: bool,
) -> dict[str, dict[str, int]]:
    """Per scale: at how many starts the walk fell, and at how many of those the scale lies
    beyond every walk with the walker's swings for this strategy's legs (``crossing``: its
    footsteps may cross; else the feet kept apart), with the torso's moment at the feet
    (``beyond_torso``) and even with it taken by the trunk (``beyond_com``): those falls are
    the walker's swings' and the robot's numbers, the rest the controller's."""
    prefix = SWING if crossing else SWING + "uncrossed_"
    out = {}
    for sc in scales:
        fell = [r for r in rows if summary.get(r, {}).get("fell", {}).get(str(sc))]
        beyond = {k: sum(1 for r, b in zip(rows, bounds, strict=True)
                         if r in fell and b.get(prefix + k) is not None and b[prefix + k] < sc)
                  for k in ("torso", "com")}  # fmt: skip
        out[str(sc)] = {"fell": len(fell), "beyond_torso": beyond["torso"],
                        "beyond_com": beyond["com"]}  # fmt: skip
    return out


def falls_beyond_lines(counts: dict[str, dict[str, int]], starts: int, crossing: bool) -> list[str]:
    """:func:`falls_beyond` as text, one line per scale with a fall."""
    legs = "its footsteps may cross" if crossing else "the feet kept apart"
    lines = []
    for sc, c in counts.items():
        if not c["fell"]:
            continue
        lines.append(f"  {float(sc):g}x: fell at {c['fell']} of {starts} starts, beyond every walk "
                     f"with the walker's swings ({legs}) at {c['beyond_torso']} of them with the "
                     f"torso's moment at the feet, at {c['beyond_com']} even with it taken by the "
                     f"trunk")  # fmt: skip
    return lines


def floats(text: str) -> list[float]:
    return [float(x) for x in text.split(",") if x.strip()]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--robot", required=True, help="built-in name or robot file path")
    p.add_argument("--jobs", type=int, default=1, help="parallel rollouts (processes)")
    p.add_argument("--json", type=Path, help="write the results as JSON")
    p.add_argument("--preset", default=str(BASE_PRESET), help="base preset (gait timing, control)")
    p.add_argument("--scales", type=floats, default=list(DEFAULT_SCALES))
    p.add_argument("--starts", type=int, default=4, help="push start times over one gait cycle")
    p.add_argument("--levels", type=floats, default=list(DEFAULT_LEVELS), help="pull, %% of m g")
    p.add_argument("--pull-sides", default="+,-", help="pull directions: +,- (left, right)")
    p.add_argument(
        "--recovery",
        type=strategy_list,
        metavar="NAME[,NAME...]",
        help=f"recovery strategies, one run each, compared ({', '.join(STRATEGIES)})",
    )
    p.add_argument("--sim", choices=("mujoco", "lip"), default="mujoco",
                   help="the humanoid (mujoco) or the point mass with its numbers (lip)")  # fmt: skip
    p.add_argument("--lever", action="store_true",
                   help="with --sim lip: forces × (z + h)/z, the torso push's load on the CoP")  # fmt: skip
    p.add_argument("--ceiling", action="store_true",
                   help="with MuJoCo: the pushes also on the point mass with the robot's numbers, at "
                        "its CoM and with the torso lever, side by side with the humanoid")  # fmt: skip
    p.add_argument("--no-observer", action="store_true", help="control.observer = false")
    p.add_argument("--repeats", type=int, default=1,
                   help="rollouts per cell, the load x (1 + k 1e-6): cells next to a first fall "
                        "read 'k/N survived' where the walk is chaotic")  # fmt: skip
    p.add_argument("--only", choices=("push", "pull"))
    p.add_argument("--set", action="append", default=[], dest="overrides",
                   metavar="section.key=value", help="extra preset override")  # fmt: skip
    p.add_argument(
        "--gain",
        action="append",
        default=[],
        metavar="name=value",
        help="whole-body QP gain (dcmviz.robots.gains.Gains field), for experiments",
    )
    args = p.parse_args(argv)
    if args.lever and args.sim != "lip":
        p.error("--lever: only with --sim lip (the humanoid has its torso)")
    if args.repeats < 1:
        p.error(f"--repeats {args.repeats}: must be at least 1")
    if args.ceiling and (args.sim != "mujoco" or args.only == "pull"):
        p.error("--ceiling: the humanoid's pushes against the point mass (--sim mujoco, pushes)")
    gains = tuple((k.strip(), float(v)) for k, v in (g.split("=", 1) for g in args.gain))
    names = args.recovery or [None]
    if len(names) == 1:
        out = _run(args, names[0], gains)
    else:
        runs = {}
        for name in names:
            print(f"\n===== recovery {name} =====", flush=True)
            runs[name] = _run(args, name, gains)
        comparison = compare_strategies(runs)
        print("\n" + "\n".join(comparison_lines(comparison)))
        out = {"robot": args.robot, "strategies": runs, "comparison": comparison}
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(out, indent=1, default=str))
    return 0


def _run(args: argparse.Namespace, recovery: str | None, gains: tuple) -> dict[str, Any]:
    """One run of the bench (every push and pull asked) with ``control.recovery = recovery``
    (None: the preset's); prints its tables and returns its JSON."""
    overrides = list(args.overrides)
    if recovery:
        overrides.append(f'control.recovery="{recovery}"')
    if args.no_observer:
        overrides.append("control.observer=false")
    base = walking_config(args.robot, args.preset, overrides, args.sim)
    mass = load_robot(args.robot).spec.mass_kg
    lever = lever_factor(args.robot)
    factor = lever if args.lever else 1.0
    cycle = 2.0 * (base.gait.t_ss + base.gait.t_ds)
    offsets = [round(cycle * i / args.starts, 3) for i in range(args.starts)]
    sides = [s.strip() for s in args.pull_sides.split(",") if s.strip()]
    jobs: list[Job] = []
    if args.only in (None, "push"):
        runs = [("push", base, factor, gains)]
        if args.ceiling:  # the same pushes on the point mass with the robot's numbers
            lip = walking_config(args.robot, args.preset, overrides, "lip")
            runs += [("lever", lip, lever, ()), ("com", lip, 1.0, ())]
        for kind, walk, f, g in runs:
            for off in offsets:
                for sc in args.scales:
                    for k in range(args.repeats):
                        cfg = push_config(walk, mass, sc, PUSH_FIRST_S + off,
                                          f * (1.0 + k * REPEAT_STEP))  # fmt: skip
                        jobs.append(Job(kind, f"start {PUSH_FIRST_S + off:.2f}s", sc, cfg,
                                        PUSH_DURATION_S, g, k))  # fmt: skip
    if args.only in (None, "pull"):
        for side in sides:
            sign = -1.0 if side.startswith("-") else 1.0
            for lv in args.levels:
                for k in range(args.repeats):
                    cfg = pull_config(base, mass, lv, sign, factor * (1.0 + k * REPEAT_STEP))
                    jobs.append(Job("pull", f"pull {'+y' if sign > 0 else '-y'}", lv, cfg,
                                    PULL_DURATION_S, gains, k))  # fmt: skip
    g = base.gait
    print(
        f"{args.robot} ({base.sim.backend}): {mass:.2f} kg; gait {g.n_steps} steps of {g.step_length} m, width "
        f"{g.step_width} m, T_ss {g.t_ss} s, T_ds {g.t_ds} s; b {base.dcm.b} s; recovery "
        f"{base.control.recovery}; observer {base.control.observer}; {len(jobs)} rollouts, "
        f"{args.jobs} jobs{'; gains ' + str(dict(gains)) if gains else ''}"
        f"{f'; forces x {factor:.3f} (the torso lever, --lever)' if args.lever else ''}",
        flush=True,
    )
    t0 = time.perf_counter()
    results = []
    with ProcessPoolExecutor(max_workers=args.jobs) if args.jobs > 1 else _Serial() as pool:
        # one start's forces in one chunk: the walk to the push is shared (_session)
        chunk = max(1, len(args.scales) * args.repeats) if args.only != "pull" else 1
        for r in pool.map(rollout, jobs, chunksize=chunk):  # one line per rollout as it ends
            results.append(r)
            fell = f"fell at {r['fall_time_s']:.2f} s" if r["fell"] else "survived"
            again = f" (repeat {r['repeat']})" if r["repeat"] else ""
            print(f"  {r['kind']} {r['row']} {r['level']:g}{again}: {r['force_n']:.1f} N, {fell}",
                  flush=True)  # fmt: skip
    wall = time.perf_counter() - t0
    out: dict[str, Any] = {
        "robot": args.robot,
        "backend": base.sim.backend,
        "mass_kg": mass,
        "gait": g.model_dump() if hasattr(g, "model_dump") else str(g),
        "b": base.dcm.b,
        "recovery": base.control.recovery,
        "observer": base.control.observer,
        "gains": dict(gains),
        "lever_factor": factor,
        "repeats": args.repeats,
        "repeat_step": REPEAT_STEP,
        "wall_time_s": wall,
        "rollouts": results,
    }
    unit_push = "x"
    if args.only in (None, "push"):
        pr = [r for r in results if r["kind"] == "push"]
        s = summarise(pr, args.scales)
        out["push"] = {"scales": args.scales, "force_per_scale_n": PAPER_FORCE_N * mass /
                       PAPER_MASS_KG, "rows": s}  # fmt: skip
        print(f"\npush ±25 N × 1 s × m/76 kg × scale (F{PAPER_FORCE_N * mass / PAPER_MASS_KG:.1f}"
              f" N per unit scale); F<t>: fell at t s")  # fmt: skip
        print(table("push scale", unit_push, s, args.scales))
        rows = [f"start {PUSH_FIRST_S + off:.2f}s" for off in offsets]
        pbounds = [push_bounds(base, PUSH_FIRST_S + off) for off in offsets]
        out["push"]["bounds"] = [{"row": r, **b} for r, b in zip(rows, pbounds, strict=True)]
        print("  beyond every footstep, in the push's scale (torso's moment at the feet / taken by"
              " the trunk; the smaller of the two pushes; '-': the pushed foot can still step"
              " out; dcmviz.sweep.bounds.footstep_bound_at), and beyond every walk whose CoP"
              " stays under the feet that stand and whose feet swing as the walker's do"
              " (swing_bound_at):")  # fmt: skip
        print("\n".join(bound_lines(rows, pbounds, args.scales)))
        crossing = STRATEGIES[base.control.recovery].crosses_legs
        beyond = falls_beyond(s, rows, pbounds, args.scales, crossing)
        out["push"]["falls_beyond_swing_bound"] = beyond
        print("\n".join(falls_beyond_lines(beyond, len(rows), crossing)))
        late = late_falls(pr)
        out["push"]["late_falls"] = late
        for x in late:
            into = "" if x["into_next_s"] is None else f", {x['into_next_s']:.1f} s into the next"
            print(f"  {x['row']}, {x['level']:g}x: fell {x['after_push_s']:.1f} s after the "
                  f"{x['push']} push ended (at {x['fall_time_s']:.2f} s{into}): the walk had "
                  "not settled")  # fmt: skip
        out["push"]["first_fall_torque_limits"] = print_first_fall_torque_limits(pr, "push")
        if args.ceiling:
            counts = {k: survived_counts([r for r in results if r["kind"] == k], args.scales)
                      for k in ("lever", "com")}  # fmt: skip
            counts["humanoid"] = survived_counts(pr, args.scales)
            out["ceiling"] = {"scales": args.scales, "starts": args.starts,
                              "lever_factor": lever, **counts}  # fmt: skip
            print(f"\nthe paper's controller on the point mass with this robot's numbers, the same "
                  f"pushes (survived starts of {args.starts}; torso lever (z + h)/z = "
                  f"{lever:.2f}):")  # fmt: skip
            head = f"{'':<26}" + "".join(f"{sc:>6g}x" for sc in args.scales)
            print(head)
            for key, label in CEILING_ROWS:
                print(f"{label:<26}" + "".join(f"{n:>7}" for n in counts[key]))
            print("\n".join(ceiling_verdicts(args.scales, args.starts, counts)) or
                  "  the humanoid survives every start at every scale")  # fmt: skip
    if args.only in (None, "pull"):
        pr = [r for r in results if r["kind"] == "pull"]
        s = summarise(pr, args.levels)
        out["pull"] = {"levels_pct": args.levels, "rows": s}
        print(f"\npull ramped over {PULL_RAMP_S:g} s and held, % of m g ({mass * GRAVITY:.0f} N)")
        print(table("pull % mg", "%", s, args.levels))
        out["pull"]["first_fall_torque_limits"] = print_first_fall_torque_limits(pr, "pull")
        out["lean"] = leans = lean_bounds(args.robot)
        print(
            "\non one foot, the largest pull the legs lean against (statics, joint ranges, CoP on"
            " the sole's inner edge; not a bound on walking, which holds more):"
        )
        for lean in leans:
            print(
                f"  trunk rolled {lean['trunk_roll_rad']:.2f} rad: {lean['pull_pct']:.1f} % of m g"
                f" (CoM {100 * lean['com_outboard_m']:.1f} cm past the sole's centre), at the end"
                f" of its range: {', '.join(lean['binding']) or '-'}"
            )
    if args.sim == "mujoco":
        busy = torque_headroom(base, gains)
        out["torque_headroom"] = busy
        print(
            "\nunpushed walk, single support: the joints nearest their torque limits "
            f"(share of ticks at ≥ {AT_LIMIT:.0%} of the limit, peak |τ|/limit):"
        )
        print("  " + "; ".join(f"{j['joint']} ({j['limit_nm']:.0f} N m) {j['at_limit_share']:.0%}, "
                              f"peak {j['peak_share']:.2f}" for j in busy[:4]))  # fmt: skip
    print(f"\n{len(jobs)} rollouts in {wall:.0f} s wall")
    return out


def strategy_list(text: str) -> list[str]:
    """``--recovery``: one strategy or several, comma-separated, each one of STRATEGIES."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    wrong = [n for n in names if n not in STRATEGIES]
    if not names or wrong:
        raise argparse.ArgumentTypeError(
            f"{', '.join(wrong) or repr(text)}: not a recovery strategy; allowed: "
            f"{', '.join(STRATEGIES)} (comma-separated for several)"
        )
    return list(dict.fromkeys(names))


def compare_strategies(runs: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """Per strategy the starts survived at each push scale (counted from its rollouts) and the
    first fall of each pull side (its summary's), and the ways each falls earlier than
    ``next_step`` when that is among them: fewer starts at a scale, or a side's pull falling
    at a lower level (or falling where ``next_step`` walks every level)."""
    table: dict[str, dict[str, Any]] = {}
    for name, run in runs.items():
        entry: dict[str, Any] = {}
        if "push" in run:
            pushes = [r for r in run["rollouts"] if r["kind"] == "push"]
            entry["push_survived_starts"] = survived_counts(pushes, run["push"]["scales"])
        if "pull" in run:
            entry["pull_first_fall_pct"] = {
                row: s["first_fall"] for row, s in run["pull"]["rows"].items()
            }
        table[name] = entry
    out: dict[str, Any] = {"strategies": table}
    first = next(iter(runs.values()))
    if "push" in first:
        out["push_scales"] = first["push"]["scales"]
    base = table.get("next_step")
    if base is not None:
        weaker: dict[str, list[str]] = {}
        for name, entry in table.items():
            notes = []
            for sc, n, n0 in zip(out.get("push_scales", []),
                                 entry.get("push_survived_starts", []),
                                 base.get("push_survived_starts", []), strict=True):  # fmt: skip
                if n < n0:
                    notes.append(f"push {sc:g}x: {n} starts against {n0}")
            for row, fall in entry.get("pull_first_fall_pct", {}).items():
                fall0 = base["pull_first_fall_pct"].get(row)
                if fall is not None and (fall0 is None or fall < fall0):
                    against = "none" if fall0 is None else f"{fall0:g} %"
                    notes.append(f"{row}: falls at {fall:g} % against {against}")
            weaker[name] = notes
        out["weaker_than_next_step"] = weaker
    return out


def comparison_lines(comparison: dict[str, Any]) -> list[str]:
    """:func:`compare_strategies` as a table, one line per strategy."""
    scales = comparison.get("push_scales", [])
    table = comparison["strategies"]
    rows = sorted({row for e in table.values() for row in e.get("pull_first_fall_pct", {})})
    head = f"{'strategy':<20}" + "".join(f"{f'{sc:g}x':>7}" for sc in scales)
    head += "".join(f"{row:>10}" for row in rows)
    lines = [
        "strategies compared (push: starts survived per scale; pull: first fall, % of m g)",
        head,
        "-" * len(head),
    ]
    for name, e in table.items():
        cells = "".join(f"{n:>7}" for n in e.get("push_survived_starts", []))
        for row in rows:
            fall = e.get("pull_first_fall_pct", {}).get(row)
            cells += f"{'-' if fall is None else format(fall, 'g') + ' %':>10}"
        lines.append(f"{name:<20}{cells}")
    for name, notes in comparison.get("weaker_than_next_step", {}).items():
        if notes:
            lines.append(f"  {name} falls earlier than next_step: {'; '.join(notes)}")
    if "weaker_than_next_step" in comparison and not any(
        comparison["weaker_than_next_step"].values()
    ):
        lines.append("  every strategy is at least as robust as next_step here")
    return lines


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    sys.exit(main())
