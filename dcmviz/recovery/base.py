"""What every push-recovery strategy (``control.recovery``) answers, and the footstep rules they share.

Each tick the walker asks its strategy for the adjustment of the DCM reference (§III-A): which
footsteps move where to absorb the DCM error ξ̃ = ξ − ξ_ref, and the change of the reference
they make, Δξ_adj (eqs. 33–35).  A strategy may also re-time the walk (:meth:`retime`) and bring
the commanded VRP back into the support its own way (:meth:`shape_vrp`).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from dcmviz.gait.plan import GaitPlan
from dcmviz.gait.terrain import EDGE_MARGIN_M, Box, Terrain
from dcmviz.gait.walk import Walk
from dcmviz.robots import Robot
from dcmviz.robots.feet import Footstep
from dcmviz.robots.reach import clamp_xy_to_reach


@dataclass(frozen=True)
class Adjustment:
    """A strategy's answer for one tick."""

    delta: np.ndarray  # (3,) Δξ_adj, the change of the DCM reference (eqs. 33–35, 49)
    target: tuple[int, np.ndarray] | None  # footstep k being adjusted and where it will land
    following: tuple[int, np.ndarray] | None  # the footstep after it, where it will land
    retarget_swing: bool = False  # the swinging foot heads for ``target`` from now on


TREADS_KEPT = 64  # footsteps whose tread a strategy remembers (RecoveryStrategy._tread)

NO_ADJUSTMENT = Adjustment(np.zeros(3), None, None)
NO_ADJUSTMENT.delta.flags.writeable = False


class RecoveryStrategy(ABC):
    """A value of ``control.recovery``: one object per walk, which may keep state between ticks."""

    name: str = ""
    crosses_legs: bool = False  # may place a footstep across the stance foot (crossover)
    uses_held_load: bool = False  # retime plans ahead with the held part of the load

    def __init__(self, robot: Robot, terrain: Terrain, b: float, dt: float) -> None:
        self.robot, self.spec = robot, robot.spec
        self.terrain, self.b, self.dt = terrain, float(b), float(dt)
        self._treads: dict[tuple[float, float], Box | None] = {}  # see _tread

    @abstractmethod
    def adjust(
        self, walk: Walk, t: float, local: float, xi_error: np.ndarray, max_adjustment: float
    ) -> Adjustment:
        """The adjustment for the DCM error ``xi_error`` at global time ``t`` (``local`` into
        the walked plan); each footstep moves at most ``max_adjustment`` (m) per axis."""

    def retime(
        self,
        walk: Walk,
        t: float,
        xi: np.ndarray,
        shift: np.ndarray,
        max_adjustment: float,
        held: np.ndarray | None = None,
    ) -> GaitPlan | None:
        """A re-timed plan to walk from now on, or None to keep the walked one (the default);
        ``xi`` is the measured DCM, ``shift`` the observer's shift of the references (eq. 48),
        ``held`` the part of it from a load that has lasted (a pull; a push's is not: it will
        be over before the steps planned now land), None: all of ``shift``."""
        return None

    def shape_vrp(
        self,
        v: np.ndarray,
        support: dict[str, bool],
        placed: dict[str, Footstep],
        shift: np.ndarray | None = None,
    ) -> np.ndarray:
        """The commanded VRP as the strategy wants it realised (default: as it is); ``shift`` is
        the observer's shift of the references (eqs. 47–49): the contact CoP lies −shift from
        the VRP."""
        return v

    # -- footholds (shared) -----------------------------------------------------------------
    def target(
        self,
        plan: GaitPlan,
        k: int,
        xi_error: np.ndarray,
        stance: Footstep,
        max_adjustment: float,
    ) -> np.ndarray:
        """Where footstep k lands for the DCM error ``xi_error`` (its x, y are read): eq. (32),
        horizontal, reachable from ``stance`` and on its tread."""
        nominal = plan.steps[k]
        a_adj = plan.adjustment_gain(k)
        nx, ny, nz = nominal.position.tolist()
        # Δv = A_adj ξ̃ (eq. 32) without its z, then the reach (clamp_to_reach), in floats
        x, y = clamp_xy_to_reach(
            self.spec, stance, nominal.side, nx + a_adj * float(xi_error[0]),
            ny + a_adj * float(xi_error[1]), nx, ny, max_adjustment,
        )  # fmt: skip
        return self.on_tread(nominal, np.array([x, y, nz]))

    def tread_box(self, nominal: Footstep) -> tuple[np.ndarray, np.ndarray] | None:
        """Bounds of Δv_xy that keep footstep ``nominal`` on its tread (see :meth:`on_tread`)."""
        if self.terrain.flat:
            return None
        box = self._tread(nominal)
        if box is None:
            return None
        p = nominal.position[:2]
        corners = np.array([box.clamp(p + d, self._tread_margin(box)) for d in
                            ((-9.0, -9.0), (9.0, 9.0), (-9.0, 9.0), (9.0, -9.0))])  # fmt: skip
        return corners.min(axis=0) - p, corners.max(axis=0) - p

    def _tread(self, nominal: Footstep) -> Box | None:
        """The tread footstep ``nominal`` stands on (None: the floor), looked up once per
        footstep: the recovery asks for the same ones every tick."""
        key = (float(nominal.position[0]), float(nominal.position[1]))
        treads = self._treads
        if key not in treads:
            if len(treads) >= TREADS_KEPT:  # an endless walk: the latest footsteps only
                treads.clear()
            treads[key] = self.terrain.support_under(nominal.position[:2])
        return treads[key]

    def _tread_margin(self, box) -> float:
        margin = EDGE_MARGIN_M + 0.5 * math.hypot(self.spec.foot_length_m, self.spec.foot_width_m)
        if box.size[0] < 2 * margin or box.size[1] < 2 * margin:
            margin = EDGE_MARGIN_M + 0.5 * self.spec.foot_length_m
        return margin

    def on_tread(self, nominal: Footstep, target: np.ndarray) -> np.ndarray:
        """On terrain an adjusted footstep stays on its nominal tread, the whole sole at least
        EDGE_MARGIN_M inside its edges, so it never straddles an edge and its height (the
        tread's, the z of its VRP waypoints) does not change: ξ_adj stays continuous.  What the
        tread cannot take goes to the next footstep like any other limit."""
        if self.terrain.flat:
            return target
        box = self._tread(nominal)
        if box is None:
            return target
        xy = box.clamp(target[:2], self._tread_margin(box))
        return np.array([xy[0], xy[1], nominal.position[2]])
