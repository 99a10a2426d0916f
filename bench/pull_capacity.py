"""How hard a robot can be pulled sideways while it stands on one foot (issue 22's diagnosis).

    python bench/pull_capacity.py --robot NAME|PATH [--tilt DEG] [--yaw DEG] [--drop M]
        [--rise M] [--starts N]

Walking under a sustained lateral pull on the torso, the robot spends half of its single support
on the foot away from the pull (the far foot): there its CoM must lean away from the pull by
h F / (m g) past the centre of pressure, h the height of the pulled point above the sole.  This
prints, for each stance foot, the largest static pull F / (m g) over postures found by SLSQP
(Pinocchio kinematics and gravity torques, scipy) with:

- the stance sole flat where it stands, the centre of pressure on the sole's edge towards the
  pull (the whole-body QP's CoP margin), the other foot lifted by at least 2 cm;
- every joint inside its range and its static torque (gravity, the pull, the contact wrench)
  inside its limit;
- the trunk within ``--tilt`` degrees of its standing orientation and turned at most ``--yaw``
  degrees;
- the CoM between ``--drop`` below and ``--rise`` above its standing height.

The answer is the best posture found from ``--starts`` starting points (a local optimum: the
robot can hold at least that much on one foot, statically).  A walk does better than static
(the DCM may drift during the far foot's single support and be caught by the next step), but the
far foot's number tells robots apart (measured with ``bench/robustness.py``): Talos (far foot
18 %) walks a 25 % pull; G1 (8 %, its ankle roll range ±15°) and Romeo (8 %) walk 10 % and fall at
15 %.  It is not the whole story: the iCub file (18 %) also falls at 15 %.  The joints it names at
their ranges and torque limits are where a robot runs out on one foot.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
from scipy.optimize import minimize

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from dcmviz import GRAVITY  # noqa: E402
from dcmviz.robots import load_robot  # noqa: E402
from dcmviz.robots.gains import Gains  # noqa: E402

LIFT_M = 0.02  # the other sole at least this high


class OneFoot:
    """The static problem of standing on ``stance`` pulled towards +y (``side`` = +1) or -y."""

    def __init__(self, robot, stance: str, side: float, args: argparse.Namespace) -> None:
        self.robot, self.side = robot, side
        self.model = m = robot.pin_model
        self.data = m.createData()
        self.mass = pin.computeTotalMass(m)
        self.stance = robot.sole_frames[stance]
        self.other = robot.sole_frames["left" if stance == "right" else "right"]
        self.torso = m.getFrameId(robot.spec.bodies.get("torso", "torso"))
        self.q0 = robot.q_nominal.copy()
        self.base0 = pin.Quaternion(self.q0[3:7]).matrix()  # a robot file's base may face -x
        pin.framesForwardKinematics(m, self.data, self.q0)
        self.sole0 = self.data.oMf[self.stance].copy()
        self.com0 = float(pin.centerOfMass(m, self.data, self.q0)[2])
        # the pulled point: the torso body's CoM, ``push_lever_m`` above the robot's CoM
        torso0 = self.data.oMf[self.torso]
        above = np.array(
            [0.0, 0.0, self.com0 + robot.push_lever_m("torso") - torso0.translation[2]]
        )
        self.pulled_local = torso0.rotation.T @ above
        self.edge = Gains.for_robot(robot).cop_margin * robot.foot_width / 2
        self.cos_tilt = np.cos(np.radians(args.tilt))
        self.yaw = np.radians(args.yaw)
        self.z_range = (self.com0 - args.drop, self.com0 + args.rise)
        self.nj = m.nq - 7

    def q(self, x: np.ndarray) -> np.ndarray:
        q = self.q0.copy()
        q[:3] = x[:3]
        q[3:7] = pin.Quaternion(pin.rpy.rpyToMatrix(*x[3:6])).coeffs()
        q[7:] = x[6:]
        return q

    def _kinematics(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        q = self.q(x)
        pin.framesForwardKinematics(self.model, self.data, q)
        return q, pin.centerOfMass(self.model, self.data, q)

    def pulled_point(self) -> np.ndarray:
        return self.data.oMf[self.torso].act(self.pulled_local)

    def ratio(self, x: np.ndarray) -> float:
        """F / (m g) in static balance: m g (p_y - c_y) = h F about the CoP on the sole's edge."""
        _, com = self._kinematics(x)
        sole = self.data.oMf[self.stance].translation
        cop_y = sole[1] + self.side * self.edge
        h = self.pulled_point()[2] - sole[2]
        return self.side * (cop_y - com[1]) / h

    def placement(self, x: np.ndarray) -> np.ndarray:
        """The stance sole where it stands, flat (6 equalities)."""
        self._kinematics(x)
        sole = self.data.oMf[self.stance]
        rotation = pin.log3(sole.rotation @ self.sole0.rotation.T)
        return np.concatenate([sole.translation - self.sole0.translation, rotation])

    def torques(self, x: np.ndarray) -> np.ndarray:
        """Static joint torques: gravity and the pull, the stance sole's wrench balancing both."""
        m, d = self.model, self.data
        q = self.q(x)
        force = np.array([0.0, self.side * self.ratio(x) * self.mass * GRAVITY, 0.0])
        pin.computeJointJacobians(m, d, q)
        pin.updateFramePlacements(m, d)
        gravity = pin.computeGeneralizedGravity(m, d, q)
        # the pulled point's linear Jacobian: the torso frame's, moved by r = point - origin
        j_torso = pin.getFrameJacobian(m, d, self.torso, pin.LOCAL_WORLD_ALIGNED)
        r = self.pulled_point() - d.oMf[self.torso].translation
        j_pull = j_torso[:3] - pin.skew(r) @ j_torso[3:]
        j_sole = pin.getFrameJacobian(m, d, self.stance, pin.LOCAL_WORLD_ALIGNED)
        pull = j_pull.T @ force
        wrench = np.linalg.lstsq(j_sole[:, :6].T, gravity[:6] - pull[:6], rcond=None)[0]
        return gravity[6:] - pull[6:] - j_sole[:, 6:].T @ wrench

    def inequalities(self, x: np.ndarray) -> np.ndarray:
        _, com = self._kinematics(x)
        rotation = pin.rpy.rpyToMatrix(*x[3:6]) @ self.base0.T  # from the standing base
        lifted = self.data.oMf[self.other].translation[2] - self.sole0.translation[2] - LIFT_M
        apart = abs(self.data.oMf[self.other].translation[1] - self.sole0.translation[1])
        shape = [
            lifted,
            apart - self.robot.foot_width,  # the other foot beside, not on, the stance foot
            rotation[2, 2] - self.cos_tilt,
            self.yaw - abs(np.arctan2(rotation[1, 0], rotation[0, 0])),
            com[2] - self.z_range[0],
            self.z_range[1] - com[2],
        ]
        return np.concatenate([shape, self.robot.torque_limit - np.abs(self.torques(x))])

    def solve(self, starts: int):
        m = self.model
        rpy = pin.rpy.matrixToRpy(pin.Quaternion(self.q0[3:7]).matrix())
        x0 = np.concatenate([self.q0[:3], rpy, self.q0[7:]])
        lo = np.r_[[-np.inf] * 6, m.lowerPositionLimit[7:]]
        hi = np.r_[[np.inf] * 6, m.upperPositionLimit[7:]]
        best = None
        for k in range(starts):
            start = x0 if k == 0 else x0 + np.random.default_rng(k).normal(0.0, 0.05, x0.size)
            res = minimize(
                lambda x: -self.ratio(x), np.clip(start, lo, hi), method="SLSQP",
                bounds=list(zip(lo, hi, strict=True)),
                constraints=[{"type": "eq", "fun": self.placement},
                             {"type": "ineq", "fun": self.inequalities}],
                options={"maxiter": 400, "ftol": 1e-9},
            )  # fmt: skip
            feasible = np.abs(self.placement(res.x)).max() < 1e-6 and (
                self.inequalities(res.x).min() > -1e-6
            )
            if feasible and (best is None or -res.fun > -best.fun):
                best = res
        return best

    def limits(self, x: np.ndarray) -> tuple[list[str], list[str]]:
        """The joints at their ranges and at their torque limits in posture x."""
        m = self.model
        names = [m.names[j] for j in range(2, m.njoints)]
        q = self.q(x)[7:]
        lo, hi = m.lowerPositionLimit[7:], m.upperPositionLimit[7:]
        at_range = [
            n for n, a, b, c in zip(names, q, lo, hi, strict=True) if min(a - b, c - a) < 1e-3
        ]
        slack = self.robot.torque_limit - np.abs(self.torques(x))
        return at_range, [n for n, s in zip(names, slack, strict=True) if s < 1e-3]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--robot", required=True, help="built-in name or robot file path")
    p.add_argument("--tilt", type=float, default=0.5, help="trunk tilt allowed, deg")
    p.add_argument("--yaw", type=float, default=0.5, help="base yaw allowed, deg")
    p.add_argument("--drop", type=float, default=0.05, help="CoM below its standing height, m")
    p.add_argument("--rise", type=float, default=0.01, help="CoM above its standing height, m")
    p.add_argument("--starts", type=int, default=4, help="SLSQP starting postures")
    args = p.parse_args(argv)
    robot = load_robot(args.robot)
    print(
        f"{robot.name} ({robot.mass:.1f} kg): static pull F/(m g) on the torso towards +y, on one "
        f"foot (trunk within {args.tilt:g} deg, yaw {args.yaw:g} deg, CoM -{args.drop:g}/"
        f"+{args.rise:g} m of standing; best of {args.starts} SLSQP starts)"
    )
    for stance, role in (("right", "far foot"), ("left", "near foot")):
        problem = OneFoot(robot, stance, +1.0, args)
        res = problem.solve(args.starts)
        if res is None:
            print(f"  {stance} ({role}): no feasible posture found")
            continue
        at_range, at_torque = problem.limits(res.x)
        print(
            f"  {stance} ({role}): {problem.ratio(res.x):6.1%}  at their ranges: "
            f"{', '.join(at_range) or '-'}; at their torque limits: {', '.join(at_torque) or '-'}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
