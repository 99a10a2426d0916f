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

Modules: ``search`` (rollouts and the boundary search), ``experiments`` (the envelope and the ramp
test), ``report`` (tables, JSON/CSV, polar plot), ``cli`` (the command line, ``main``).
"""

from dcmviz.sweep.cli import PROG, build_parser, main
from dcmviz.sweep.experiments import CONTROLLERS, SweepSettings, envelope, ramp_test
from dcmviz.sweep.report import plot_polar, ramp_table, ratios, table, write_envelope
from dcmviz.sweep.search import Boundary, Rollouts, Trial, find_boundary, push_window, survives

__all__ = [
    "Boundary",
    "CONTROLLERS",
    "PROG",
    "Rollouts",
    "SweepSettings",
    "Trial",
    "build_parser",
    "envelope",
    "find_boundary",
    "main",
    "plot_polar",
    "push_window",
    "ramp_table",
    "ramp_test",
    "ratios",
    "survives",
    "table",
    "write_envelope",
]
