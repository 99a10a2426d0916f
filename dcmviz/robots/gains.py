"""Gains, weights and limits of the whole-body QP's tasks and constraints.

The defaults hold for any humanoid without per-robot tuning: task gains are accelerations
(1/s², 1/s) on errors in m and rad, the force weights act on wrenches divided by the robot's
mass, and the contact limits (CoP, torsion) come from the robot's sole size.  A robot file may
still set any field in its ``[controller]`` table (docs/robots.md); :meth:`Gains.for_robot`
applies them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass
class Gains:
    """Task gains (1/s², 1/s) and weights (dimensionless, on errors in m/s² or rad/s²)."""

    kp_foot: float = 600.0
    kd_foot: float = 50.0
    # a compliant trunk (the base carries the locked torso): it absorbs the swing leg's angular
    # momentum that the sole's CoP and torsion cannot (G1 0.4 m/s: 0.06 m wide feet)
    kp_base: float = 30.0
    kd_base: float = 11.0  # 2 √kp_base, critically damped
    # the trunk leans along the contact force m g e_z − F̂ a sustained external force asks for
    # (0: upright; 1: as far as that force is tilted)
    trunk_lean: float = 1.0
    # the trunk tilts sideways (roll about the walking direction) at most this far (rad) from
    # its target when the QP tips it to realise a force the soles cannot (TrunkTilt), braking
    # with trunk_tilt_acceleration rad/s², its rate brought within reach of that in
    # trunk_tilt_horizon s (0: no bound); trunk_pitch_limit the same forwards and backwards
    # (0: free).  Off by default.  Measured with 0.3 (docs/robots.md, "The trunk's tilt bound,
    # measured again"): the G1 under a held pull holds 17.5 % with every strategy (multi_step
    # falls at 15 % without), Talos 30 % with every strategy, the push pairs survive where they
    # did; but the G1's next_step then falls at 20 % +y (11.3 s), which it holds without, and
    # on roll and pitch it cost the 0.2 s pushes forwards and backwards 6-13 %
    trunk_tilt_limit: float = 0.0
    trunk_pitch_limit: float = 0.0
    trunk_tilt_horizon: float = 0.05
    trunk_tilt_acceleration: float = 20.0
    kp_posture: float = 30.0
    kd_posture: float = 10.0
    touchdown_depth: float = 0.01  # m below the footstep for a support foot not yet touching
    kd_stance: float = 10.0  # stance foot: a = -kd v (kills drift)
    k_angular_momentum: float = 5.0  # L̇ = -k L
    k_moment_observer: float = 10.0  # 1/s, external-moment observer gain (0: off)
    # s: an external load held this long is taken by the feet (and leaned into); the moment of a
    # shorter push is absorbed as angular momentum (SustainedLoad; 0: every moment at the feet)
    sustained_time_s: float = 1.0
    # s: the held load settles to a new value with this time constant (a first-order lag) where
    # its rules switch, so the references shifted by it do not jump (SustainedLoad)
    sustained_settle_s: float = 0.2
    w_force: float = 1000.0
    w_angular_momentum: float = 0.5
    w_base: float = 3.0
    w_foot: float = 10.0  # a foot that cannot follow its path (joint ranges) yields to the CoM
    # the swing sole's height weighs this many times w_foot as it lands (ramped in over 60–90 %
    # of single support): with w_foot alone the QP let the sole lag its path by 3 mm on the way
    # down and catch up at the end, touching 20–550 ms early at up to 0.15 m/s (talos_fast,
    # g1_fast); with 5, ≤ 30 ms early at ≤ 0.05 m/s (tests/test_touchdown.py).  10 lands softer
    # still but loses Talos's 29 N s crossover and romeo_push.toml: a recovering step must land
    # where the CoM needs it more than softly (1: off)
    w_landing: float = 5.0
    w_posture: float = 0.05
    w_qdd_reg: float = 1e-5
    w_wrench_reg: float = 1e-4  # on w / m
    joint_limits: bool = True  # joint ranges as (soft) acceleration bounds in the QP
    leg_clearance: bool = True  # the legs kept apart (soft; active only when they come close)
    w_joint_limits: float = 1e6  # weight of a joint-range violation (rad/s²) where unavoidable
    joint_limit_horizon: float = 0.05  # s, look-ahead of the joint-range bounds
    joint_limit_margin: float = 0.0  # rad kept from each end of a joint's range
    friction: float = 0.7  # μ of the pyramid (MuJoCo's floor has 1.0)
    torsion: float | None = None  # m, |τ_z| ≤ torsion · f_z (None: from the sole's width)
    min_normal_force: float = 5.0  # N on a support foot
    cop_margin: float = 0.9  # fraction of the half sole used for the CoP

    @classmethod
    def for_robot(cls, robot: Any) -> Gains:
        """The defaults with the robot file's ``[controller]`` values (``robot.controller``)."""
        return cls(**dict(getattr(robot, "controller", None) or {}))
