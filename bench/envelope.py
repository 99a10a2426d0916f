"""Tracking across a robot's walking envelope: random settings, one walk each (issue 9, item 4).

    python bench/envelope.py --robot talos|g1|romeo|PATH --n 40 --seed 1 [--sim mujoco|lip] [--jobs 2]

Each setting is drawn uniformly from the robot's envelope (step length, width, turn, T_ss, T_ds,
CoM height → b, k_ξ, order, mode, step adjustment and observer on/off) and walked without
pushes.  A walk passes when it reaches its end without falling, with horizontal DCM error
|ξ − ξ_ref|_xy < 3 cm and vertical < 2 cm at every tick, and < 1 cm at the end.  Prints the
fraction that passes and every failure with its settings and the limit it broke.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dcmviz import GRAVITY  # noqa: E402
from dcmviz.config import Config, ConfigError  # noqa: E402
from dcmviz.robots import load_robot  # noqa: E402

HORIZONTAL_LIMIT_M = 0.03
VERTICAL_LIMIT_M = 0.02
FINAL_LIMIT_M = 0.01
N_STEPS = 8
CONTINUOUS_S = 10.0


@dataclass(frozen=True)
class Envelope:
    step_length: tuple[float, float]
    step_width: tuple[float, float]
    turn: tuple[float, float] = (-0.3, 0.3)
    t_ss: tuple[float, float] = (0.5, 1.2)
    t_ds: tuple[float, float] = (0.1, 0.4)
    k_xi: tuple[float, float] = (1.0, 6.0)


ENVELOPES = {
    "talos": Envelope(step_length=(-0.15, 0.40), step_width=(0.16, 0.30)),
    "g1": Envelope(step_length=(-0.10, 0.25), step_width=(0.20, 0.30)),
}


def scaled_envelope(spec) -> Envelope:
    """Talos's envelope scaled by the robot's standing CoM height, its step lengths, widths and
    turns kept inside the robot's reach (steps up to the share of ``max_step_length_m`` Talos
    walks, 0.40 / 0.45; widths from ``min_step_width_m`` + 1 cm; |turn| ≤ ``max_turn_rad``)."""
    talos = ENVELOPES["talos"]
    s = spec.com_height_m / load_robot("talos").spec.com_height_m
    lo_w = max(talos.step_width[0] * s, spec.min_step_width_m + 0.01)
    hi_w = min(max(talos.step_width[1] * s, lo_w + 0.05), spec.max_step_width_m)
    turn = min(talos.turn[1], spec.max_turn_rad)
    # Talos walks its envelope up to 0.40 of its 0.45 m reach: the same share of the robot's
    share = talos.step_length[1] / load_robot("talos").spec.max_step_length_m
    longest = min(talos.step_length[1] * s, share * spec.max_step_length_m)
    return Envelope(
        step_length=(max(talos.step_length[0] * s, -longest), longest),
        step_width=(lo_w, hi_w),
        turn=(-turn, turn),
    )


def draw(robot: str, rng: np.random.Generator) -> dict:
    """One random setting of the envelope, as preset sections."""
    env = ENVELOPES.get(robot)
    spec = load_robot(robot).spec
    if env is None:  # another robot: Talos's envelope scaled by the CoM height, inside its reach
        env = scaled_envelope(spec)
    height = rng.uniform(*spec.com_height_range_m)
    u = lambda r: float(rng.uniform(*r))  # noqa: E731
    return {
        "robot": {"model": robot},
        "gait": {
            "mode": str(rng.choice(["plan", "continuous"])),
            "n_steps": N_STEPS,
            "step_length": u(env.step_length),
            "step_width": u(env.step_width),
            "turn": u(env.turn),
            "t_ss": u(env.t_ss),
            "t_ds": u(env.t_ds),
        },
        "dcm": {"order": int(rng.choice([0, 1, 3, 5])), "b": math.sqrt(height / GRAVITY)},
        "control": {
            "k_xi": u(env.k_xi),
            "step_adjustment": bool(rng.integers(2)),
            "observer": bool(rng.integers(2)),
        },
    }


def walk(job: tuple[int, dict, str]) -> dict:
    """Walk one setting; the errors and the verdict."""
    from dcmviz.session import Session

    index, sections, sim = job
    try:
        config = Config().replace(sim={"backend": sim}, **sections)
    except ConfigError as err:
        return {"index": index, "sections": sections, "ok": False, "why": f"refused: {err}"}
    session = Session(config, backend=sim)
    duration = session.plan.duration + 1.0 if config.gait.mode == "plan" else CONTINUOUS_S
    worst = np.zeros(2)
    ticks = 0

    def watch(tick) -> None:
        nonlocal ticks
        e = tick.command.xi - tick.command.xi_ref
        worst[0] = max(worst[0], math.hypot(e[0], e[1]))
        worst[1] = max(worst[1], abs(e[2]))
        ticks += 1

    session.subscribe(watch)
    wall = time.perf_counter()
    session.run(duration)
    wall = time.perf_counter() - wall
    final = session.tick().dcm_error_m if session.tick() else math.inf
    why = []
    if session.fell:
        why.append(f"fell at {session.metrics.fall_time_s:.2f} s")
    if worst[0] >= HORIZONTAL_LIMIT_M:
        why.append(f"horizontal error {worst[0] * 100:.1f} cm ≥ {HORIZONTAL_LIMIT_M * 100:.0f}")
    if worst[1] >= VERTICAL_LIMIT_M:
        why.append(f"vertical error {worst[1] * 100:.1f} cm ≥ {VERTICAL_LIMIT_M * 100:.0f}")
    if not session.fell and final >= FINAL_LIMIT_M:
        why.append(f"final error {final * 100:.1f} cm ≥ {FINAL_LIMIT_M * 100:.0f}")
    return {
        "index": index,
        "sections": sections,
        "ok": not why,
        "why": "; ".join(why),
        "horizontal_m": float(worst[0]),
        "vertical_m": float(worst[1]),
        "final_m": float(final),
        "sim_s": float(session.t),
        "wall_s": wall,
    }


def describe(sections: dict) -> str:
    g, d, c = sections["gait"], sections["dcm"], sections["control"]
    return (
        f"{g['mode']:10s} L={g['step_length']:+.2f} w={g['step_width']:.2f} "
        f"turn={g['turn']:+.2f} Tss={g['t_ss']:.2f} Tds={g['t_ds']:.2f} "
        f"h={GRAVITY * d['b'] ** 2:.3f} order={d['order']} k_xi={c['k_xi']:.1f} "
        f"adj={'on' if c['step_adjustment'] else 'off'} obs={'on' if c['observer'] else 'off'}"
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--robot", default="talos", help="built-in name or robot file")
    p.add_argument("--n", type=int, default=40, help="random settings")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--sim", nargs="?", const="mujoco", choices=("mujoco", "lip"), default="mujoco",
        help="backend (a bare --sim is mujoco)",
    )  # fmt: skip
    p.add_argument("--jobs", type=int, default=2, help="parallel walks (processes)")
    args = p.parse_args(argv)
    try:
        spec = load_robot(args.robot).spec  # a built-in name or a robot file, checked as a whole
    except ValueError as err:
        print(f"--robot {args.robot}: {err}", file=sys.stderr)
        return 2
    if args.robot not in ENVELOPES:
        env = scaled_envelope(spec)
        print(
            f"{spec.name}: envelope step_length {env.step_length[0]:+.3f}…{env.step_length[1]:+.3f} m, "
            f"step_width {env.step_width[0]:.3f}…{env.step_width[1]:.3f} m, turn ±{env.turn[1]:.3f} rad, CoM height "
            f"{spec.min_com_height_m:.3f}–{spec.max_com_height_m:.3f} m"
        )
    rng = np.random.default_rng(args.seed)
    jobs = [(i, draw(args.robot, rng), args.sim) for i in range(args.n)]
    t0 = time.perf_counter()
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            results = list(pool.map(walk, jobs))
    else:
        results = [walk(j) for j in jobs]
    wall = time.perf_counter() - t0
    ok = [r for r in results if r["ok"]]
    print(
        f"{args.robot} on {args.sim}, seed {args.seed}: {len(ok)}/{len(results)} "
        f"= {len(ok) / len(results):.0%} walk to the end within the limits "
        f"(horizontal < {HORIZONTAL_LIMIT_M * 100:.0f} cm, vertical < {VERTICAL_LIMIT_M * 100:.0f}"
        f" cm, final < {FINAL_LIMIT_M * 100:.0f} cm); {wall:.0f} s wall"
    )
    for key, label in (("horizontal_m", "horizontal"), ("vertical_m", "vertical")):
        e = np.array([r.get(key, math.nan) for r in results]) * 100
        print(
            f"  largest {label} error per walk: median {np.nanmedian(e):.2f} cm, "
            f"90 % {np.nanpercentile(e, 90):.2f} cm, max {np.nanmax(e):.2f} cm"
        )
    falls = sum("fell" in r["why"] for r in results)
    print(f"  falls: {falls}; sim {sum(r.get('sim_s', 0.0) for r in results):.0f} s")
    for r in results:
        if not r["ok"]:
            print(f"  FAIL #{r['index']:3d} {describe(r['sections'])}: {r['why']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
