"""Real-time factor of the Talos default walk (MuJoCo + whole-body QP) and its per-tick split.

    python bench/sim.py [PRESET] [--duration S]

Prints the real-time factor of one headless run and how one control tick divides into physics,
Pinocchio, QP build, QP solve, walker and the rest (µs per tick and share), all from that run.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from dcmviz.config import load_preset
from dcmviz.sim.mujoco_sim import MujocoBackend
from dcmviz.walker import Walker

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("preset", nargs="?", default=str(ROOT / "presets" / "walk_forward.toml"))
    parser.add_argument("--duration", type=float, default=None, help="s of simulated time")
    args = parser.parse_args()
    config = load_preset(args.preset)
    backend = MujocoBackend(config.robot.model)
    state = backend.reset()
    walker = Walker(config, mass=backend.mass, dt=backend.control_dt)
    walker.reset(state)
    duration = args.duration or config.sim.duration
    walker_s = 0.0
    ticks = 0
    fell = False
    start = time.perf_counter()
    while state.t < duration - 1e-9:
        t0 = time.perf_counter()
        command = walker.step(state)
        walker_s += time.perf_counter() - t0
        state = backend.step(command)
        ticks += 1
        if backend.fell():
            fell = True
            break
    wall = time.perf_counter() - start
    parts = dict(backend.timings)
    parts["walker"] = walker_s
    parts["other"] += wall - sum(parts.values())  # loop overhead, measurement, bookkeeping
    print(
        f"{config.robot.model}: {state.t:.2f} s simulated in {wall:.2f} s wall, "
        f"real-time factor {state.t / wall:.2f}"
        f" ({ticks} ticks of {backend.control_dt * 1e3:.1f} ms, "
        f"{backend.n_substeps} physics substeps each)"
    )
    print(f"fell: {fell}; steps completed: {walker.steps_completed}")
    print(f"{'part':<12}{'µs/tick':>10}{'share':>8}")
    for name, seconds in parts.items():
        print(f"{name:<12}{seconds / ticks * 1e6:>10.1f}{seconds / wall:>8.1%}")
    print(f"{'total':<12}{wall / ticks * 1e6:>10.1f}{1:>8.0%}")


if __name__ == "__main__":
    main()
