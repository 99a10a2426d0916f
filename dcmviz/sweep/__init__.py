"""Push-recovery envelopes, gain maps and tuning:
``python -m dcmviz.sweep PRESET [--sim lip|mujoco] [--directions 8] [--push-duration 0.2]
[--phase 0.5] [--out DIR] [--jobs N | --address HOST:PORT] [--resume] [--grid KEY=A:B:N ...]``.

For each horizontal push direction (0 = +x forward, counter-clockwise) and each of three
controllers

* ``tracking``: DCM tracking only, eq. (24) (no step adjustment, no observer);
* ``step_adjustment``: step adjustment and the adapted DCM reference, eqs. (27)–(35), (40)/(41);
* ``step_adjustment+observer``: the same plus the disturbance observer, eqs. (42)–(49);

(or ``preset``: the preset's own flags; or, with ``--strategies next_step,multi_step,
multi_step_timing``, tracking and each recovery strategy of ``control.recovery`` with step
adjustment on and the observer off, side by side in one table and one polar plot) the largest
push impulse J = |F| T_push (N·s) that the
walk survives is found: a push of the given duration starts at a fraction ``--phase`` of the
single support of the ``--step``-th step (a mid-walk step), and the robot keeps walking until
``--settle-steps`` step periods after the push (or to the end of the plan with ``--full``).
Survived = not fallen by then.

Survival need not be monotone in the impulse (a larger push can trigger a different, luckier
footstep adaptation), so a coarse grid (``--coarse`` points) over the bracket comes first: the
result is the bisected boundary below the *first* failing grid point, and any grid point that
survives above it is reported as ``non_monotone``.

Execution: one rollout is one Ray task on a local Ray instance (``--jobs`` CPUs, default all) or
a cluster (``--address``); ``--jobs 1`` runs serially in this process with identical numbers.
The searches of all cells advance concurrently (each cell's next probe is submitted as soon as
its previous one is answered).  Every finished rollout is appended to ``OUT/rollouts.jsonl`` at
once; ``--resume`` answers the rollouts found there without running them.  A task whose worker
dies is retried by Ray.  A progress bar shows rollouts done, rate and time left.

``--grid control.k_xi=1:6:6 dcm.b=0.28:0.32:3`` maps the envelope over one or two preset keys:
``map.png`` (heatmap of ``--metric`` weakest|mean|area, the preset's values marked),
``map.csv``, ``map.json``.  ``--ramp-test`` instead bisects the held force of the preset's ramped
push (tug of war) for each controller: the smallest force at which the robot falls, to the end
of ``sim.duration``.

Outputs in ``--out``: ``envelope.json``, ``envelope.csv``, ``envelope.png`` (polar plot), or the
map's, or ``ramp.json``; and ``rollouts.jsonl``.  Exit 2 with a one-line reason for bad input,
130 when interrupted.  Tuning (Ray Tune + Optuna) is ``python -m dcmviz.sweep.tune``
(:mod:`dcmviz.sweep.tuning`).

Modules: ``search`` (rollouts and the boundary search), ``store`` (rollouts on disk),
``runner`` (serial and Ray execution, the concurrent driver), ``experiments`` (envelope, ramp
test, fixed probes), ``maps``, ``tuning``, ``report`` (metrics, tables, JSON/CSV, polar plot),
``cli`` (the command line, ``main``).
"""

from dcmviz.sweep.cells import Cell, RolloutEvent, SweepRun
from dcmviz.sweep.cli import PROG, build_parser, main
from dcmviz.sweep.experiments import (
    CONTROLLERS,
    PRESET_CONTROLLER,
    Execution,
    SweepSettings,
    envelope,
    ramp_test,
    with_controller,
)
from dcmviz.sweep.maps import Axis, gain_map, parse_axis, write_map
from dcmviz.sweep.report import (
    METRICS,
    envelope_metric,
    plot_polar,
    ramp_table,
    ratios,
    table,
    write_envelope,
)
from dcmviz.sweep.runner import RayRunner, SerialRunner, make_runner, open_runner, ray_init
from dcmviz.sweep.scheduler import run_cells
from dcmviz.sweep.search import (
    Boundary,
    BoundarySearch,
    RolloutResult,
    Rollouts,
    Trial,
    find_boundary,
    prefix_snapshot,
    push_window,
    rollout,
    survives,
)
from dcmviz.sweep.store import ROLLOUTS_FILE, RolloutStore, trial_key

__all__ = [
    "Axis",
    "Boundary",
    "BoundarySearch",
    "CONTROLLERS",
    "Cell",
    "Execution",
    "METRICS",
    "PRESET_CONTROLLER",
    "PROG",
    "ROLLOUTS_FILE",
    "RayRunner",
    "RolloutEvent",
    "RolloutResult",
    "RolloutStore",
    "Rollouts",
    "SerialRunner",
    "SweepRun",
    "SweepSettings",
    "Trial",
    "build_parser",
    "envelope",
    "envelope_metric",
    "find_boundary",
    "gain_map",
    "main",
    "make_runner",
    "open_runner",
    "parse_axis",
    "plot_polar",
    "prefix_snapshot",
    "push_window",
    "ramp_table",
    "ramp_test",
    "ratios",
    "ray_init",
    "rollout",
    "run_cells",
    "survives",
    "table",
    "trial_key",
    "with_controller",
    "write_envelope",
    "write_map",
]
