"""Real-time factor of the Talos default walk (MuJoCo + whole-body QP) and its per-tick split.

    python bench/sim.py [PRESET ...] [--duration S] [--record PATH | --compare PATH]

Without a preset it runs ``walk_forward`` (Talos) and ``g1_push`` (G1), one after the other.
Prints the real-time factor of one headless run and how one control tick divides into physics,
Pinocchio, QP build, QP solve, walker and the rest (µs per tick and share), all from that run,
and the controller's share (everything but physics) as a multiple of the physics step. The
split is in CPU time of the running thread by default (``--clock cpu``), which other processes
on a shared machine disturb far less than elapsed time (``--clock wall``).

``--profile`` runs the same walk as a :class:`~dcmviz.session.Session` (what the runner, the
sweeps and the dashboard step) under cProfile and lists every function that costs ≥ 5 µs per
tick by itself (``--min-us``), grouped by where it lives, then the tick measured from outside:
``Session.step()`` against bare ``mj_step`` substeps of the same model from the same states.

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
from dcmviz.session.session import make_backend
from dcmviz.sim import mujoco_sim
from dcmviz.sim.mujoco_sim import MujocoBackend
from dcmviz.sim.wbc import solver
from dcmviz.walker import Walker

ROOT = Path(__file__).resolve().parents[1]
PRESETS = ("walk_forward.toml", "g1_push.toml")  # the presets of issue 23's targets


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("preset", nargs="*", default=[str(ROOT / "presets" / p) for p in PRESETS])
    parser.add_argument("--duration", type=float, default=None, help="s of simulated time")
    parser.add_argument(
        "--clock",
        choices=("cpu", "wall"),
        default="cpu",
        help="cpu: this thread's CPU time (steady on a shared machine); wall: elapsed time",
    )
    parser.add_argument("--record", type=Path, help="save every tick's outputs to this .npz")
    parser.add_argument("--compare", type=Path, help="compare every tick's outputs with this .npz")
    parser.add_argument(
        "--profile", action="store_true", help="per-function cost of a Session tick (cProfile)"
    )
    parser.add_argument("--min-us", type=float, default=5.0, help="--profile: list parts ≥ this")
    args = parser.parse_args()
    if len(args.preset) > 1 and (args.record or args.compare):
        parser.error("--record / --compare take one preset")
    summary = []
    for preset in args.preset:
        if not Path(preset).exists() and (ROOT / "presets" / f"{preset}.toml").exists():
            preset = str(ROOT / "presets" / f"{preset}.toml")  # a built-in preset by name
        args1 = argparse.Namespace(**{**vars(args), "preset": preset})
        summary.append(profile(args1) if args.profile else run(args1))
        print()
    for line in summary:
        print(line)


def run(args) -> str:
    """One headless run with the per-tick split; returns the summary line."""
    clock = time.thread_time if args.clock == "cpu" else time.perf_counter
    mujoco_sim._clock = solver._clock = clock
    config = load_preset(args.preset)
    # as a Session builds it: the preset's terrain (the stairs' treads) under the backend
    backend = make_backend(config, load_robot(config.robot.model), "mujoco")
    state = backend.reset()
    walker = Walker(config, backend.robot, mass=backend.mass, dt=backend.control_dt,
                    terrain=backend.terrain)  # fmt: skip
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
    ratio = controller / parts["physics"]
    print(f"controller / physics: {ratio:.2f}x")
    summary = (
        f"{Path(args.preset).stem}: controller / physics {ratio:.2f}x, real time "
        f"×{backend.control_dt * ticks / wall:.1f} on one core ({args.clock} time; "
        f"×{state.t / elapsed:.1f} wall)"
    )
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
    return summary


def profile(args) -> str:
    """``--profile``: cProfile over whole Session ticks, and Session.step against mj_step."""
    import cProfile
    import pstats

    import mujoco

    from dcmviz.session import Session

    config = load_preset(args.preset)
    duration = args.duration or config.sim.duration
    session = Session(config, backend="mujoco")
    profiler = cProfile.Profile(time.thread_time)
    profiler.enable()
    session.run(duration)
    profiler.disable()
    ticks = session.metrics.ticks
    stats = pstats.Stats(profiler)
    total = sum(row[2] for row in stats.stats.values())  # tottime
    rows = []
    for (path, line, name), (_, calls, tottime, cumtime, _) in stats.stats.items():
        where = path.split("/dcmviz/", 1)[-1] if "/dcmviz/" in path else Path(path).name
        rows.append(
            (tottime / ticks * 1e6, cumtime / ticks * 1e6, calls / ticks, where, line, name)
        )
    rows.sort(reverse=True)
    print(
        f"{config.robot.model} {Path(args.preset).name}: {ticks} ticks under cProfile, "
        f"{total / ticks * 1e6:.0f} µs/tick in all (thread CPU time; cProfile adds ~0.3 µs a call)"
    )
    print(f"{'self µs':>8} {'cum µs':>8} {'calls':>6}  function")
    shown = 0.0
    for own, cum, calls, where, line, name in rows:
        if own < args.min_us:
            break
        shown += own
        print(f"{own:8.1f} {cum:8.1f} {calls:6.1f}  {where}:{line} {name}")
    print(f"{shown:8.1f}          listed ({shown / (total / ticks * 1e6):.0%} of the tick)")

    # from outside: Session.step() against bare mj_step on the same model from the same states
    session = Session(config, backend="mujoco")
    backend = session.backend
    model, data = backend.model, backend.data
    bare = mujoco.MjData(model)
    n = min(ticks, round(duration / backend.control_dt))
    step_s = bare_s = 0.0
    for _ in range(n):
        mujoco.mj_copyData(bare, model, data)
        t0 = time.thread_time()
        session.step()
        t1 = time.thread_time()
        for _ in range(backend.n_substeps):
            mujoco.mj_step(model, bare)
        t2 = time.thread_time()
        step_s, bare_s = step_s + t1 - t0, bare_s + t2 - t1
        if session.fell:
            break
    line = (
        f"Session.step(): {step_s / n * 1e6:.1f} µs/tick; bare mj_step × {backend.n_substeps}: "
        f"{bare_s / n * 1e6:.1f} µs; controller / physics {(step_s - bare_s) / bare_s:.2f}x, "
        f"real time ×{backend.control_dt / (step_s / n):.1f} on one core"
    )
    print(line)
    return f"{Path(args.preset).stem}: {line}"


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
