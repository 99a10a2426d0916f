"""Point-mass (lip) speed: real-time factor of the default walk and the time of a full sweep.

    python bench/lip.py [--preset presets/walk_forward.toml] [--jobs N] [--no-sweep]

Prints numbers measured in this run: the real-time factor (simulated / wall seconds) of the
undisturbed walk, the same with a rerun recording attached, and the wall time of a push-recovery
sweep of 8 directions × 3 controllers (python -m dcmviz.sweep defaults).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from dcmviz.config import load_preset  # noqa: E402
from dcmviz.record import Recorder  # noqa: E402
from dcmviz.session import Session  # noqa: E402
from dcmviz.sweep import SweepSettings, envelope  # noqa: E402


def walk_rtf(config, *, record: bool = False, repeats: int = 3) -> tuple[float, float, float]:
    """Best wall-clock real-time factor of ``repeats`` runs, its per-tick time (µs), and the best
    real-time factor by process CPU time (robust when other jobs share the cores)."""
    best = best_cpu = 0.0
    tick_us = 0.0
    for _ in range(repeats):
        session = Session(config, backend="lip")
        recorder = None
        if record:
            recorder = Recorder()
            tmp = tempfile.NamedTemporaryFile(suffix=".rrd", delete=False)
            recorder.start(session, tmp.name)
        wall, cpu = time.perf_counter(), time.process_time()
        metrics = session.run(config.sim.duration)
        if recorder is not None:
            recorder.stop()
            os.unlink(tmp.name)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        best_cpu = max(best_cpu, session.t / cpu)
        rtf = session.t / wall
        if rtf > best:
            best, tick_us = rtf, 1e6 * wall / metrics.ticks
    return best, tick_us, best_cpu


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--preset", default=str(ROOT / "presets" / "walk_forward.toml"))
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    p.add_argument("--no-sweep", action="store_true")
    args = p.parse_args()
    config = load_preset(args.preset)
    print(f"preset {config.name!r}, {config.sim.duration:.1f} s simulated, lip backend")
    rtf, tick, rtf_cpu = walk_rtf(config)
    print(
        f"  walk:            {rtf:6.1f}x real time ({tick:5.0f} µs per 5 ms tick); "
        f"by CPU time {rtf_cpu:6.1f}x"
    )
    rtf_rec, tick_rec, rtf_rec_cpu = walk_rtf(config, record=True)
    print(
        f"  walk + .rrd:     {rtf_rec:6.1f}x real time ({tick_rec:5.0f} µs per tick; "
        f"recording costs {tick_rec / tick:.2f}x); by CPU time {rtf_rec_cpu:6.1f}x"
    )
    if args.no_sweep:
        return
    print(f"  load average before the sweep: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    settings = SweepSettings(backend="lip", jobs=args.jobs)
    cpu = time.process_time()
    result = envelope(config, settings)
    runs = sum(r["runs"] for r in result["rows"])
    print(
        f"  sweep 8 dir x 3 controllers: {result['wall_time_s']:5.1f} s wall with {args.jobs} "
        f"jobs ({runs} rollouts, {result['wall_time_s'] / runs * args.jobs * 1e3:.0f} ms each "
        f"per job; parent CPU {time.process_time() - cpu:.1f} s)"
    )
    print(f"  load average now: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
