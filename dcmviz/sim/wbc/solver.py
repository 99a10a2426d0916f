"""Torque-level whole-body controller: small tasks and constraints feeding one QP (mink style).

Decision variables ``x = [q̈ (nv), w_left (6), w_right (6)]`` with ``w = [f; τ]`` the contact
wrench at the sole origin in world axes (the dual of the LOCAL_WORLD_ALIGNED sole Jacobian).
The torques follow from the actuated rows of the floating-base dynamics

    M q̈ + h = Sᵀ τ + Σ J_iᵀ w_i      ⇒      τ = (M q̈ + h - Σ J_iᵀ w_i)[6:].

Cost: ``Σ_k weight_k ‖A_k x - b_k‖²`` over the tasks; constraints: the 6 unactuated rows of the
dynamics (equality), stance feet held (equality), friction pyramid, unilateral normal force,
CoP inside the sole rectangle and torque limits. A foot gets a wrench only if it is *measured*
in contact *and* the walker schedules it as support; otherwise its wrench is bounded to zero and
it tracks the walker's foot target (swing, or coming down to touch down).
Solved with daqp (dense active set; fastest measured on this QP, see DESIGN.md).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import daqp
import numpy as np

from dcmviz.dcm.sustained import SustainedLoad
from dcmviz.robots import SIDES, Robot
from dcmviz.robots.gains import Gains
from dcmviz.sim.wbc.constraints import (
    INF,
    Constraint,
    ContactWrenchCone,
    FloatingBaseDynamics,
    JointLimits,
    StanceFoot,
    TorqueLimits,
    TrunkTilt,
)
from dcmviz.sim.wbc.context import Context, Kinematics
from dcmviz.sim.wbc.layout import Layout
from dcmviz.sim.wbc.legs import LegClearance
from dcmviz.sim.wbc.tasks import (
    AngularMomentumTask,
    AnkleStops,
    BaseOrientationTask,
    ContactForceTask,
    FootTask,
    PostureTask,
    Task,
)
from dcmviz.walker.state import WalkerCommand

# the clock of ``timings``: wall time; bench/sim.py may set CPU time (time.thread_time)
_clock = time.perf_counter


@dataclass
class Solution:
    """The QP's answer for one tick."""

    tau: np.ndarray  # (nu,) N m, Pinocchio joint order
    qdd: np.ndarray  # (nv,)
    wrenches: dict[str, np.ndarray]  # side -> (6,) [f; τ] at the sole, world axes
    ok: bool  # False: the QP failed and the previous torques were kept
    exitflag: int


class WholeBodyController:
    """Builds and solves the QP from a list of tasks and constraints each tick."""

    def __init__(self, robot: Robot, gains: Gains | None = None, control_dt: float = 0.002) -> None:
        self.robot = robot
        self.gains = g = gains or Gains.for_robot(robot)
        self.layout = lay = Layout(robot.nv)
        self.kinematics = Kinematics(robot)
        mass = robot.mass
        self.tasks: list[Task] = [
            ContactForceTask(lay, mass, g.w_force),
            AngularMomentumTask(lay, mass, g.k_angular_momentum, g.w_angular_momentum),
            base := BaseOrientationTask(
                lay, g.kp_base, g.kd_base, g.w_base, robot.base_offset, g.trunk_lean, mass
            ),
            *(
                FootTask(
                    s,
                    lay,
                    g.kp_foot,
                    g.kd_foot,
                    g.w_foot,
                    g.touchdown_depth,
                    g.w_landing,
                    AnkleStops.of(robot, s, g.joint_limit_margin, g.joint_limit_horizon)
                    if g.joint_limits
                    else None,
                )
                for s in SIDES
            ),
            PostureTask(robot, lay, g.kp_posture, g.kd_posture, g.w_posture),
        ]
        self.constraints: list[Constraint] = [
            FloatingBaseDynamics(lay),
            *(StanceFoot(s, lay, g.kd_stance) for s in SIDES),
            *(ContactWrenchCone(s, lay, robot, g) for s in SIDES),
            TorqueLimits(robot, lay),
        ]
        if g.trunk_tilt_limit > 0:
            self.constraints.append(
                TrunkTilt(lay, base, g.trunk_tilt_limit, g.trunk_tilt_horizon,
                          g.trunk_tilt_acceleration, pitch_limit=g.trunk_pitch_limit)
            )  # fmt: skip
        if g.joint_limits:
            self.constraints.append(
                JointLimits(robot, lay, g.joint_limit_horizon, g.joint_limit_margin)
            )
        if g.leg_clearance:
            self.constraints.append(LegClearance(robot, lay))
        nx = lay.nx
        self.n_rows = sum(c.rows for c in self.constraints)
        self._A = np.zeros((self.n_rows, nx))
        # daqp's bounds: first nx simple bounds on the scaled x' (below), then the rows' bounds,
        # which the constraints write in place (rows are not scaled)
        self._bounds_lo = np.zeros(nx + self.n_rows)
        self._bounds_up = np.zeros(nx + self.n_rows)
        self._sense = np.zeros(nx + self.n_rows, dtype=np.int32)
        self._reg = np.full(nx, g.w_qdd_reg)
        for s in SIDES:
            self._reg[lay.wrench[s]] = 0.0  # the wrench term depends on the sole's rotation
        # Σ of the squared forces at the sole's 4 corners (times 4) for a wrench [f; τ] in sole
        # axes: ‖f‖² + τ_x²/a_y² + τ_y²/a_x² + τ_z²/(a_x² + a_y²), a the half-length and
        # half-width (the corners' grasp matrix G has G Gᵀ = 4 diag(I, a_y², a_x², a_x² + a_y²)):
        # a moment costs what the corner forces making it cost, so the split of the wrenches
        # between the feet keeps each CoP away from the sole's edges unless a task needs it.
        ax, ay = robot.foot_length / 2, robot.foot_width / 2
        self._wrench_reg = g.w_wrench_reg / mass**2
        self._moment_diag = np.array([1 / ay**2, 1 / ax**2, 1 / (ax**2 + ay**2)])
        self._moment_gram = tuple(np.zeros((len(SIDES), 3, 3)) for _ in range(3))  # R, R m, (R m)Rᵀ
        self._H_constant = np.diag(self._reg)  # regularisation + state-independent AᵀA
        for s in SIDES:
            i = lay.wrench[s].start
            self._H_constant[i : i + 3, i : i + 3] += self._wrench_reg * np.eye(3)
        for task in self.tasks:
            if task.constant_gram is not None:
                self._H_constant += task.weight * task.constant_gram
        # a soft row's violation s costs ½ s²/ρ, the cost of a task of weight 1/ρ (daqp)
        self._rho_soft = 1.0 / g.w_joint_limits
        self._scale = np.ones(nx)
        self._scale[robot.nv :] = mass
        self._scale_outer = np.outer(self._scale, self._scale)
        self._H = np.zeros((nx, nx))  # the QP, rewritten each tick
        self._c = np.zeros(nx)
        # each constraint's rows of A, lo, up (views, filled in place each tick) and daqp sense
        self._rows = []
        row = 0
        for con in self.constraints:
            r = slice(row, row + con.rows)
            b = slice(nx + row, nx + row + con.rows)
            sense = 8 if con.soft else 0
            self._rows.append(
                (con, self._A[r], self._bounds_lo[b], self._bounds_up[b], self._sense[b], sense)
            )
            row += con.rows
        self._weighted: dict[Task, np.ndarray] = {}  # weight Aᵀ of the tasks with a constant A
        self._torque_lo = -robot.torque_limit
        self._H_s = np.zeros((nx, nx))  # the QP in scaled variables, rewritten each tick
        self._c_s = np.zeros(nx)
        self._A_s = np.zeros((self.n_rows, nx))
        # simple bounds of x' = x / d: q̈ free (±INF / 1); a wrench free (±INF / m) where its foot
        # bears weight, else fixed at 0 (0 / m)
        self._bounds_lo[: robot.nv] = -INF / self._scale[: robot.nv]
        self._bounds_up[: robot.nv] = INF / self._scale[: robot.nv]
        self._free_lo = {s: -INF / self._scale[lay.wrench[s]] for s in SIDES}
        self._free_up = {s: INF / self._scale[lay.wrench[s]] for s in SIDES}
        self.timings = {"qp_build": 0.0, "qp_solve": 0.0}  # s, summed since the last reset
        self.last: Solution | None = None
        self.failures = 0  # QPs that failed (previous torques held)
        self._held_tau = np.zeros(robot.nu)  # torques of the last solved QP, N m
        self.sustained = SustainedLoad(g.sustained_time_s, control_dt, g.sustained_settle_s)
        self._daqp: daqp.Model | None = None  # the solver's workspace, set up at the first tick
        self.reset()

    def reset(self) -> None:
        """Start afresh, e.g. after the simulation is reset: a failed QP holds zero torques
        (not those of the previous run), and the timings, failure count and last solution clear."""
        self._held_tau = np.zeros(self.robot.nu)
        for key in self.timings:
            self.timings[key] = 0.0
        self.last = None
        self.failures = 0
        self.sustained.reset()

    def get_state(self) -> tuple:
        """What the next tick depends on besides the context (a resume from a tick): the torques
        held for a failed QP and the sustained load's window."""
        return self._held_tau.copy(), self.sustained.get_state()

    def set_state(self, state: tuple) -> None:
        """Continue from :meth:`get_state`'s copy."""
        held, sustained = state
        self._held_tau = held.copy()
        self.sustained.set_state(sustained)

    def _daqp_solve(self, H: np.ndarray, c: np.ndarray, A: np.ndarray, sense: np.ndarray):
        """daqp on this tick's numbers in one workspace set up at the first tick: the same
        solution as ``daqp.solve`` (which sets up a workspace per call), about 24 µs a tick less
        (Talos qp_solve: 73.7 → 50.0 µs, bench/sim.py)."""
        model = self._daqp
        if model is None:
            model = self._daqp = daqp.Model()
            model.setup(H, c, A, self._bounds_up, self._bounds_lo, sense)
            settings = model.settings
            settings["rho_soft"] = self._rho_soft
            model.settings = settings
        else:
            model.update(H=H, f=c, A=A, bupper=self._bounds_up, blower=self._bounds_lo,
                         sense=sense)  # fmt: skip
        return model.solve()

    def solve(self, ctx: Context, cmd: WalkerCommand, in_contact: dict[str, bool]) -> Solution:
        """τ for this tick; ``in_contact`` is the *measured* contact of each sole."""
        t0 = _clock()
        lay = self.layout
        nv = lay.nv
        for s in SIDES:
            ctx.active[s] = bool(in_contact[s] and cmd.support[s])
        self.sustained.update(cmd.t, cmd.f_hat, ctx.external_moment)
        ctx.sustained_force = self.sustained.force
        ctx.sustained_moment = self.sustained.moment
        H = self._H
        np.copyto(H, self._H_constant)
        c = self._c
        c.fill(0.0)
        # the moments' regularisation R diag(m) Rᵀ of both soles as (R m) Rᵀ, in one batch
        rotations, scaled, gram = self._moment_gram
        for j, s in enumerate(SIDES):
            rotations[j] = ctx.sole_rotation[s]
        np.multiply(rotations, self._moment_diag, out=scaled)
        np.matmul(scaled, rotations.transpose(0, 2, 1), out=gram)
        gram *= self._wrench_reg
        for j, s in enumerate(SIDES):
            i = lay.wrench[s].start + 3
            H[i : i + 3, i : i + 3] += gram[j]
        weighted = self._weighted
        for task in self.tasks:
            out = task.compute(ctx, cmd)
            if out is None:
                continue
            A, b = out
            wA = weighted.get(task) if task.constant_matrix else None
            if wA is None:  # wAᵀ of a constant A is computed once
                wA = task.weight * A.T
                if task.constant_matrix:
                    weighted[task] = wA
            if task.constant_gram is None:
                H += wA @ A
            c -= wA @ b
        bounds_lo, bounds_up, sense = self._bounds_lo, self._bounds_up, self._sense
        sense[:] = 0
        for s in SIDES:
            sl = lay.wrench[s]
            if ctx.active[s]:
                bounds_lo[sl], bounds_up[sl] = self._free_lo[s], self._free_up[s]
            else:
                bounds_lo[sl], bounds_up[sl] = 0.0, 0.0
                sense[sl] = 5
        for con, A_rows, lo_rows, up_rows, sense_rows, inequality in self._rows:
            # each constraint rewrites the same entries
            if con.compute(ctx, cmd, A_rows, lo_rows, up_rows):
                sense_rows[:] = 5
            elif inequality:
                sense_rows[:] = inequality
        # solve in scaled variables x = D x' (wrenches in units of m·1 m/s²): H' = D H D, A' = A D
        d = self._scale
        H_s = np.multiply(H, self._scale_outer, out=self._H_s)
        c_s = np.multiply(c, d, out=self._c_s)
        A_s = np.multiply(self._A, d, out=self._A_s)
        t1 = _clock()
        x, _, exitflag, _ = self._daqp_solve(H_s, c_s, A_s, sense)
        x = x * d
        t2 = _clock()
        self.timings["qp_build"] += t1 - t0
        self.timings["qp_solve"] += t2 - t1
        # 1: optimal; 2: optimal with soft constraints (joint ranges) relaxed where nothing
        # else was feasible — a solution all the same
        ok = exitflag in (1, 2) and math.isfinite(x.sum())  # a NaN or inf anywhere
        if ok:
            qdd = x[:nv]
            wr = {s: x[lay.wrench[s]].copy() for s in SIDES}
            tau = ctx.M[6:] @ qdd + ctx.h[6:]
            for s in SIDES:
                tau -= ctx.sole_jacobian[s][:, 6:].T @ wr[s]
            np.maximum(tau, self._torque_lo, out=tau)  # = np.clip, without its overhead
            np.minimum(tau, self.robot.torque_limit, out=tau)
            self._held_tau = tau
        else:
            self.failures += 1
            qdd = np.zeros(nv)
            wr = {s: np.zeros(6) for s in SIDES}
            tau = self._held_tau
        self.last = Solution(tau=tau, qdd=qdd.copy(), wrenches=wr, ok=ok, exitflag=int(exitflag))
        return self.last
