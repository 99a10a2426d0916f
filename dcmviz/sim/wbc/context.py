"""The per-tick state every task and constraint reads: Pinocchio evaluated once at (q, v)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from dcmviz.robots import Robot

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@dataclass
class Context:
    """Everything the tasks need about the current state, computed once per tick by Pinocchio."""

    q: np.ndarray
    v: np.ndarray
    M: np.ndarray
    h: np.ndarray  # nle + joint damping
    com: np.ndarray
    com_velocity: np.ndarray
    angular_momentum: np.ndarray  # about the CoM, world axes
    base_rotation: np.ndarray
    base_omega: np.ndarray  # world axes
    sole_position: dict[str, np.ndarray] = field(default_factory=dict)
    sole_rotation: dict[str, np.ndarray] = field(default_factory=dict)
    sole_velocity: dict[str, np.ndarray] = field(default_factory=dict)  # (6,) [lin; ang], world
    sole_jacobian: dict[str, np.ndarray] = field(default_factory=dict)  # (6, nv) LWA
    sole_drift: dict[str, np.ndarray] = field(default_factory=dict)  # (6,) J̇ v, classical
    active: dict[str, bool] = field(default_factory=dict)  # wrench variable allowed
    external_moment: np.ndarray = field(default_factory=lambda: np.zeros(3))  # estimate, N m
    # Pinocchio's model and its data at (q, v) (joints' placements, Jacobians, accelerations at
    # q̈ = 0): a constraint evaluating frames of its own reads them (dcmviz.sim.wbc.legs)
    model: object = None
    data: object = None


class Kinematics:
    """Pinocchio evaluation of a :class:`Context` from (q, v)."""

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.model = robot.pin_model
        self.data = self.model.createData()
        self._damping = np.zeros(self.model.nv)
        self._damping[6:] = robot.damping
        self._sole_frames = list(robot.sole_frames.items())

    def context(self, q: np.ndarray, v: np.ndarray) -> Context:
        """M, h, CoM, centroidal angular momentum, sole poses/Jacobians/drifts at (q, v)."""
        m, d = self.model, self.data
        # computeAllTerms also leaves the joints' spatial accelerations for q̈ = 0 in data (data.a:
        # the drift J̇ q̇); computeCentroidalMomentum refines its CoM and momentum (to 1e-15)
        pin.computeAllTerms(m, d, q, v)
        pin.computeCentroidalMomentum(m, d, q, v)
        x, y, z, w = q[3:7].tolist()  # base rotation from the unit quaternion (faster than oMi[1])
        rot = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
        position, rotation, jacobian, velocity, drift = {}, {}, {}, {}, {}
        for side, fid in self._sole_frames:
            placement = pin.updateFramePlacement(m, d, fid)  # a copy of data.oMf[fid]
            position[side] = placement.translation
            rotation[side] = placement.rotation
            jacobian[side] = pin.getFrameJacobian(m, d, fid, _LWA)
            velocity[side] = pin.getFrameVelocity(m, d, fid, _LWA).vector  # owns its Motion
            drift[side] = pin.getFrameClassicalAcceleration(m, d, fid, _LWA).vector
        return Context(
            q,
            v,
            d.M.copy(),
            d.nle + self._damping * v,
            d.com[0].copy(),
            d.vcom[0].copy(),
            d.hg.angular.copy(),
            rot,
            rot @ v[3:6],
            position,
            rotation,
            velocity,
            jacobian,
            drift,
            {},
            np.zeros(3),
            m,
            d,
        )
