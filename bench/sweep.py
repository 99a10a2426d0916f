"""Sweep throughput: rollouts per second serially (1 core) and on a local Ray instance with all
cores, the speed-up, how an envelope's cost grows with directions × bisection iterations, and
what a 1,000-configuration gain map costs on one machine and on N machines.

    python bench/sweep.py [--preset presets/walk_forward.toml] [--sim lip|mujoco] [--jobs N]

Every number is measured in this run (Ray's start-up excluded: the workers are warmed first);
the projections are arithmetic on the measured rate.  Other jobs on the machine lower the
rates: the load average is printed before and after.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from dcmviz.config import load_preset  # noqa: E402
from dcmviz.sweep import (  # noqa: E402
    Execution,
    RayRunner,
    SerialRunner,
    SweepSettings,
    envelope,
)


def rate(config, settings: SweepSettings, runner) -> tuple[float, int, float]:
    """(rollouts per second, rollouts, wall s) of one envelope."""
    result = envelope(config, settings, Execution(runner=runner))
    n = result["rollouts"]["run"]
    return n / result["wall_time_s"], n, result["wall_time_s"]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--preset", default=str(ROOT / "presets" / "walk_forward.toml"))
    p.add_argument("--sim", choices=("lip", "mujoco"), default="lip")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    args = p.parse_args()
    config = load_preset(args.preset)
    base = SweepSettings(
        backend=args.sim, directions=8, grid=6, iterations=4, controllers=("step_adjustment",)
    )
    print(
        f"preset {config.name!r}, {args.sim}; {os.cpu_count()} cores, load average "
        f"{os.getloadavg()[0]:.1f}"
    )

    # 1. throughput: the same envelope serially and on Ray
    serial_rate, n, wall = rate(config, base, SerialRunner())
    print(f"  serial (1 core):  {serial_rate:6.2f} rollouts/s ({n} rollouts in {wall:.1f} s)")
    t0 = time.perf_counter()
    ray_runner = RayRunner(num_cpus=args.jobs)
    warm = SweepSettings(**{**base.__dict__, "directions": 2 * args.jobs, "iterations": 1})
    envelope(config, warm, Execution(runner=ray_runner))  # workers up, modules imported
    startup = time.perf_counter() - t0
    ray_rate, n, wall = rate(config, base, ray_runner)
    print(
        f"  Ray ({args.jobs} CPUs):      {ray_rate:6.2f} rollouts/s ({n} rollouts in {wall:.1f} s; "
        f"Ray start + warm-up {startup:.1f} s, not counted)"
    )
    print(f"  speed-up:         {ray_rate / serial_rate:6.2f}x on {args.jobs} CPUs")

    # 2. an envelope's cost: directions × (coarse grid + bisection iterations) rollouts
    print("  envelope cost (1 controller, coarse grid 6, on Ray):")
    print(
        f"    {'directions':>10} {'iterations':>10} {'rollouts':>9} {'≤ D·(6+i)':>10} {'wall s':>7} {'per rollout ms':>15}"
    )
    for directions, iterations in ((4, 4), (8, 4), (8, 8), (16, 4)):
        s = SweepSettings(**{**base.__dict__, "directions": directions, "iterations": iterations})
        r, n, wall = rate(config, s, ray_runner)
        print(
            f"    {directions:>10} {iterations:>10} {n:>9} {directions * (6 + iterations):>10} "
            f"{wall:>7.1f} {1e3 * wall / n:>15.0f}"
        )
    ray_runner.close()
    print(f"  load average now {os.getloadavg()[0]:.1f}")

    # 3. on paper: a 1,000-configuration gain map, 8 directions, 3 controllers, grid 6 + 7
    rollouts = 1000 * 8 * 3 * (6 + 7)
    latency = 1.0 / serial_rate  # one rollout on one core
    depth = 1 + 7  # rounds of a search that cannot run in parallel: the grid, then each midpoint
    print(
        f"  a 1,000-config map (8 directions x 3 controllers x ≤ 13 probes = {rollouts:,} "
        f"rollouts), at {ray_rate:.1f} rollouts/s per {args.jobs}-core machine:"
    )
    for machines in (1, 4, 16, 64):
        seconds = max(rollouts / (machines * ray_rate), depth * latency)
        print(f"    {machines:>3} machine(s): {seconds / 3600:7.2f} h")


if __name__ == "__main__":
    main()
