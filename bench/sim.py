"""Real-time factor of the Talos default walk (MuJoCo + whole-body QP) and its per-tick split.

    python bench/sim.py [PRESET] [--duration S] [--record PATH | --compare PATH]

Prints the real-time factor of one headless run and how one control tick divides into physics,
Pinocchio, QP build, QP solve, walker and the rest (µs per tick and share), all from that run,
and the controller's share (everything but physics) as a multiple of the physics step. The
split is in CPU time of the running thread by default (``--clock cpu``), which other processes
on a shared machine disturb far less than elapsed time (``--clock wall``).

``--record PATH`` saves every tick's command (ξ, ξ_ref, ξ_adj, v_ref, v_cmd, forces, foot
targets), torques, q̈ and contact wrenches to an ``.npz``; ``--compare PATH`` reruns the same
preset and prints the largest difference from that recording (an optimisation must keep it
≤ 1e-9). The preset's pushes are applied, so step adjustment and the observer are exercised.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from dcmviz.config import load_preset
from dcmviz.robots import load_robot
from dcmviz.sim import mujoco_sim
from dcmviz.sim.mujoco_sim import MujocoBackend
from dcmviz.sim.wbc import solver
from dcmviz.walker import Walker

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("preset", nargs="?", default=str(ROOT / "presets" / "walk_forward.toml"))
    parser.add_argument("--duration", type=float, default=None, help="s of simulated time")
    parser.add_argument(
        "--clock",
        choices=("cpu", "wall"),
        default="cpu",
        help="cpu: this thread's CPU time (steady on a shared machine); wall: elapsed time",
    )
    parser.add_argument("--record", type=Path, help="save every tick's outputs to this .npz")
    parser.add_argument("--compare", type=Path, help="compare every tick's outputs with this .npz")
    args = parser.parse_args()
    clock = time.thread_time if args.clock == "cpu" else time.perf_counter
    mujoco_sim._clock = solver._clock = clock
    config = load_preset(args.preset)
    backend = MujocoBackend(load_robot(config.robot.model))
    state = backend.reset()
    walker = Walker(config, backend.robot, mass=backend.mass, dt=backend.control_dt)
    walker.reset(state)
    duration = args.duration or config.sim.duration
    walker_s = 0.0
    ticks = 0
    fell = False
    trace: dict[str, list[np.ndarray]] = {}
    tracing = args.record is not None or args.compare is not None
    start = clock()
    wall_start = time.perf_counter()
    while state.t < duration - 1e-9:
        if config.pushes:
            _apply_pushes(backend, config.pushes, state.t)
        t0 = clock()
        command = walker.step(state)
        walker_s += clock() - t0
        state = backend.step(command)
        ticks += 1
        if tracing:
            _trace(trace, command, backend.wbc.last)
        if backend.fell():
            fell = True
            break
    wall = clock() - start  # the loop's time on the chosen clock
    elapsed = time.perf_counter() - wall_start
    parts = dict(backend.timings)
    parts["walker"] = walker_s
    parts["other"] += wall - sum(parts.values())  # loop overhead, measurement, bookkeeping
    print(
        f"{config.robot.model}: {state.t:.2f} s simulated in {elapsed:.2f} s wall "
        f"({wall:.2f} s {args.clock}), real-time factor {state.t / elapsed:.2f}"
        f" ({ticks} ticks of {backend.control_dt * 1e3:.1f} ms, "
        f"{backend.n_substeps} physics substeps each)"
    )
    print(f"fell: {fell}; steps completed: {walker.steps_completed}")
    print(f"{'part':<12}{'µs/tick':>10}{'share':>8}   ({args.clock} time)")
    for name, seconds in parts.items():
        print(f"{name:<12}{seconds / ticks * 1e6:>10.1f}{seconds / wall:>8.1%}")
    print(f"{'total':<12}{wall / ticks * 1e6:>10.1f}{1:>8.0%}")
    controller = wall - parts["physics"]
    print(f"controller / physics: {controller / parts['physics']:.2f}x")
    if args.record is not None:
        np.savez_compressed(args.record, **{k: np.array(v) for k, v in trace.items()})
        print(f"recorded {ticks} ticks to {args.record}")
    if args.compare is not None:
        saved = np.load(args.compare)
        worst = max((float(np.max(np.abs(np.array(trace[k]) - saved[k]))), k) for k in saved.files)
        n = len(saved["t"])
        same = n == ticks
        print(
            f"largest difference over {n} ticks: {worst[0]:.3g} ({worst[1]}); ticks match: {same}"
        )


def _apply_pushes(backend: MujocoBackend, pushes, t: float) -> None:
    """The preset's pushes as persistent forces (ramped like the session does, linearly)."""
    backend.clear_external_forces()
    for push in pushes:
        if push.start <= t < push.start + push.duration:
            ramp = min(1.0, (t - push.start) / push.ramp) if push.ramp > 0 else 1.0
            backend.set_external_force(push.body, np.asarray(push.force, float) * ramp)


def _trace(trace: dict[str, list[np.ndarray]], command, solution) -> None:
    rows = {
        "t": np.array([command.t]),
        "xi": command.xi,
        "xi_ref": command.xi_ref,
        "xi_adj": command.xi_adj,
        "v_ref": command.v_ref,
        "v_cmd": command.v_cmd,
        "com_force": command.com_force,
        "contact_force": command.contact_force,
        "f_hat": command.f_hat,
        "v_cmd_rate": command.v_cmd_rate,
        "feet": np.concatenate(
            [
                np.concatenate([f.position, f.velocity, f.acceleration, [f.yaw, f.yaw_rate]])
                for f in command.feet.values()
            ]
        ),
        "tau": solution.tau,
        "qdd": solution.qdd,
        "wrenches": np.concatenate(list(solution.wrenches.values())),
    }
    for k, v in rows.items():
        trace.setdefault(k, []).append(np.array(v, dtype=float))


if __name__ == "__main__":
    main()
