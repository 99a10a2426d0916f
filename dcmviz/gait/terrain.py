"""Terrain: flat floor plus boxes (platforms, stepping stones) and stairs built from boxes.

Pure geometry, no physics: the planner asks how high the ground is under a sole and which tread
a point lies on; the MuJoCo scene and the dashboard draw the same boxes.  A preset's
``[terrain]`` section (see :mod:`dcmviz.config`) is turned into a :class:`Terrain` by
:func:`terrain_of`.  World frame, z up; heights are those of the top faces.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

EDGE_MARGIN_M = 0.02  # a sole keeps this far inside its tread's edges


@dataclass(frozen=True)
class Box:
    """A block standing on the floor: top face at ``top`` (m), ``size`` (x, y) about ``center``."""

    center: tuple[float, float]  # m, world x, y of the top face's centre
    size: tuple[float, float]  # m, extent along the box's own x and y
    top: float  # m, height of the top face above the floor
    yaw: float = 0.0  # rad

    @property
    def solid(self) -> tuple[np.ndarray, np.ndarray]:
        """Centre (3,) and half-sizes (3,) of the block from the floor up to the top face (m):
        the MuJoCo geom, the dashboard's and the recording's box."""
        return (
            np.array([self.center[0], self.center[1], 0.5 * self.top]),
            np.array([0.5 * self.size[0], 0.5 * self.size[1], 0.5 * self.top]),
        )

    def local(self, xy: np.ndarray) -> np.ndarray:
        """Points (…, 2) in the box's frame (origin at its centre)."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        d = np.asarray(xy, dtype=float) - np.asarray(self.center)
        return np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], axis=-1)

    def contains(self, xy: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """True where a point lies on the top face, at least ``margin`` inside its edges."""
        p = self.local(xy)
        hx, hy = 0.5 * self.size[0] - margin, 0.5 * self.size[1] - margin
        return (np.abs(p[..., 0]) <= hx) & (np.abs(p[..., 1]) <= hy)

    def contains_point(self, x: float, y: float, margin: float = 0.0) -> bool:
        """:meth:`contains` of the one point (x, y), in floats (the recovery asks every tick)."""
        px, py = self._local_point(x, y)
        return abs(px) <= 0.5 * self.size[0] - margin and abs(py) <= 0.5 * self.size[1] - margin

    def clamp(self, xy: np.ndarray, margin: float) -> np.ndarray:
        """The nearest point of the top face at least ``margin`` inside its edges (in floats:
        one point, asked every tick)."""
        x, y = np.asarray(xy, dtype=float).tolist()
        px, py = self._local_point(x, y)
        hx = max(0.5 * self.size[0] - margin, 0.0)
        hy = max(0.5 * self.size[1] - margin, 0.0)
        qx, qy = min(max(px, -hx), hx), min(max(py, -hy), hy)
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return np.array((self.center[0] + (c * qx - s * qy), self.center[1] + (s * qx + c * qy)))

    def _local_point(self, x: float, y: float) -> tuple[float, float]:
        """:meth:`local` of the one point (x, y), the same operations in floats."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        dx, dy = x - self.center[0], y - self.center[1]
        return c * dx + s * dy, -s * dx + c * dy


@dataclass(frozen=True)
class Terrain:
    """The floor (z = 0) and boxes on it; the ground is the highest top face under a point."""

    boxes: tuple[Box, ...] = ()

    @property
    def flat(self) -> bool:
        return not self.boxes

    def height_at(self, xy: np.ndarray) -> np.ndarray:
        """Ground height (m) under points (…, 2)."""
        xy = np.asarray(xy, dtype=float)
        h = np.zeros(xy.shape[:-1])
        for box in self.boxes:
            h = np.where(box.contains(xy), np.maximum(h, box.top), h)
        return h

    def support_under(self, xy: np.ndarray) -> Box | None:
        """The box whose top face a point (2,) stands on (None: the floor)."""
        x, y = np.asarray(xy, dtype=float).tolist()
        best: Box | None = None
        for box in self.boxes:
            if box.contains_point(x, y) and (best is None or box.top > best.top):
                best = box
        return best

    def sole_heights(self, corners: np.ndarray) -> np.ndarray:
        """Ground height under each corner (…, 4, 2) of a sole (or of many): unequal heights
        straddle an edge."""
        return self.height_at(corners)


def stairs_boxes(
    start: float, rise: float, run: float, count: int, width: float, landing: float
) -> tuple[Box, ...]:
    """Stairs along +x from x = ``start``: ``count`` treads ``run`` deep, each ``rise`` higher
    (``rise`` < 0: down from a landing of height count·|rise| that ends at ``start``), then a
    landing ``landing`` long at the top (up) or the floor (down)."""
    boxes = []
    if rise > 0:
        for i in range(count):
            depth = run if i < count - 1 else run + landing
            x0 = start + i * run
            boxes.append(Box((x0 + 0.5 * depth, 0.0), (depth, width), (i + 1) * rise))
    else:
        h = -rise
        top = count * h
        x_far = start - landing  # the landing reaches back behind the robot's start
        boxes.append(Box((0.5 * (x_far + start), 0.0), (start - x_far, width), top))
        for i in range(1, count):
            x0 = start + (i - 1) * run
            boxes.append(Box((x0 + 0.5 * run, 0.0), (run, width), top - i * h))
    return tuple(boxes)


def terrain_of(section: Any) -> Terrain:
    """The :class:`Terrain` of a preset's ``[terrain]`` section (None: flat floor)."""
    if section is None:
        return Terrain()
    boxes: list[Box] = []
    stairs = section.stairs
    if stairs is not None:
        boxes += stairs_boxes(
            stairs.start, stairs.rise, stairs.run, stairs.count, stairs.width, stairs.landing
        )
    for b in section.boxes:
        boxes.append(Box(tuple(b.center), tuple(b.size), b.top, b.yaw))
    return Terrain(tuple(boxes))
