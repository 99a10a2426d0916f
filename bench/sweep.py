"""Sweep throughput: rollouts per second serially (1 core) and on a local Ray instance with all
cores, the speed-up, how an envelope's cost grows with directions × bisection iterations, and
what a 1,000-configuration gain map costs on one machine and on N machines.

    python bench/sweep.py [--preset presets/walk_forward.toml] [--sim lip|mujoco] [--jobs N]
    python bench/sweep.py --sim mujoco --vs PATH [--rounds 2]

``--vs PATH`` (another checkout of dcmviz, e.g. ``git worktree add /tmp/old <commit>``) measures
only the serial rate, this checkout's and that one's in turns (``--rounds`` each, every run in its
own process, ``QUICK`` envelope: 4 directions, grid 6, 2 iterations), and prints the ratio: a
speed claim measured in one run.

Every number is measured in this run (Ray's start-up excluded: the workers are warmed first);
the projections are arithmetic on the measured rate.  Other jobs on the machine lower the
rates: the load average is printed before and after.
"""

from __future__ import annotations

import argparse
import os
import subprocess
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


QUICK = {"directions": 4, "grid": 6, "iterations": 2}  # the --vs envelope
_SERIAL_RATE = """
import sys
sys.path[:0] = [{root!r}, {root!r} + "/bench"]
import dcmviz
assert dcmviz.__file__.startswith({root!r}), dcmviz.__file__
from dcmviz.config import load_preset
from dcmviz.sweep import SerialRunner, SweepSettings
from sweep import rate
s = SweepSettings(backend={sim!r}, controllers=("step_adjustment",), **{quick!r})
r, n, wall = rate(load_preset({preset!r}), s, SerialRunner())
print(r, n, wall)
"""


def serial_rate_of(root: Path, preset: str, sim: str) -> tuple[float, int, float]:
    """(rollouts/s, rollouts, wall s) of the QUICK envelope with ``root``'s dcmviz, serially in
    a process of its own."""
    code = _SERIAL_RATE.format(root=str(root), sim=sim, quick=QUICK, preset=preset)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    r, n, wall = out.stdout.split()[-3:]
    return float(r), int(n), float(wall)


def compare(other: Path, preset: str, sim: str, rounds: int) -> None:
    """This checkout's serial rate against ``other``'s, in turns."""
    ours, theirs = [], []
    print(f"serial rollouts/s, {sim}, {QUICK}; this checkout ({ROOT}) against {other}:")
    for i in range(rounds):
        for root, rates in ((other, theirs), (ROOT, ours)):
            r, n, wall = serial_rate_of(root, preset, sim)
            rates.append(r)
            print(f"  round {i + 1}: {root}: {r:.3f} rollouts/s ({n} rollouts in {wall:.1f} s)")
    per_round = ", ".join(f"{a / b:.2f}x" for a, b in zip(ours, theirs, strict=True))
    print(
        f"  this checkout / {other.name}: {sum(ours) / sum(theirs):.2f}x (per round: {per_round})"
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--preset", default=str(ROOT / "presets" / "walk_forward.toml"))
    p.add_argument("--sim", choices=("lip", "mujoco"), default="lip")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    p.add_argument("--vs", type=Path, help="another dcmviz checkout: serial rate against it only")
    p.add_argument("--rounds", type=int, default=2, help="--vs: runs of each checkout")
    args = p.parse_args()
    if args.vs is not None:
        if not (args.vs / "dcmviz" / "__init__.py").is_file():
            p.error(f"--vs {args.vs}: expected a dcmviz checkout (with dcmviz/__init__.py)")
        compare(args.vs.resolve(), str(Path(args.preset).resolve()), args.sim, args.rounds)
        return
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
