"""Sole rectangles and support polygons: pure 2-D geometry in the ground plane (m, world x-y).

``sole_corners``, ``convex_hull`` and ``project_to_polygon`` are the scalar helpers the point mass
uses each tick (moved here from :mod:`dcmviz.sim.lip` so that planning can use them without
importing a backend); ``soles_corners``, ``hull_depth`` and ``rectangle_gap`` are their
vectorised forms for checking a whole plan at once (:mod:`dcmviz.gait.feasibility`).
"""

from __future__ import annotations

import math

import numpy as np

# corners of a unit sole in its own frame, counter-clockwise: front-left, back-left, back-right,
# front-right (× length/2, width/2)
_UNIT_CORNERS = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])


def sole_corners(position: np.ndarray, yaw: float, length: float, width: float) -> np.ndarray:
    """(4, 2) corners of a sole rectangle, counter-clockwise."""
    c, s = math.cos(yaw), math.sin(yaw)
    hl, hw = 0.5 * length, 0.5 * width
    local = np.array([[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]])
    rot = np.array([[c, -s], [s, c]])
    return position[:2] + local @ rot.T


def soles_box(
    placements: tuple[tuple[float, float, float], ...], length: float, width: float
) -> tuple[float, float, float, float]:
    """(x_lo, y_lo, x_hi, y_hi): the world-axes box of sole rectangles at ``placements`` (x, y,
    yaw).  In closed form, each sole's farthest corner from its centre ±(|c| l + |s| w, |s| l +
    |c| w), l, w the half sizes: the corners' own min and max (:func:`sole_corners`), within an
    ulp (a matrix product may fuse their multiply-adds; equal at yaw 0)."""
    hl, hw = 0.5 * length, 0.5 * width
    x_lo = y_lo = math.inf
    x_hi = y_hi = -math.inf
    for x, y, yaw in placements:
        c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
        ex, ey = c * hl + s * hw, s * hl + c * hw
        x_lo, x_hi = min(x_lo, x - ex), max(x_hi, x + ex)
        y_lo, y_hi = min(y_lo, y - ey), max(y_hi, y + ey)
    return x_lo, y_lo, x_hi, y_hi


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull (Andrew's monotone chain) of (N, 2) points."""
    pts = sorted(map(tuple, np.round(points, 12)))
    if len(pts) <= 2:
        return np.array(pts)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def project_to_polygon(point: np.ndarray, polygon: np.ndarray) -> tuple[np.ndarray, float]:
    """Closest point of a convex CCW polygon to ``point`` (2,), and the distance (0 inside).

    Plain floats: the polygons have at most 8 vertices and this runs twice per control tick.
    """
    px, py = float(point[0]), float(point[1])
    verts = polygon.tolist()
    n = len(verts)
    for i in range(n):  # inside test first: the common case costs one pass of cross products
        ax, ay = verts[i]
        bx, by = verts[(i + 1) % n]
        if (bx - ax) * (py - ay) - (by - ay) * (px - ax) < 0.0:
            break
    else:
        return np.array([px, py]), 0.0
    best = (math.inf, px, py)
    for i in range(n):
        ax, ay = verts[i]
        bx, by = verts[(i + 1) % n]
        ex, ey = bx - ax, by - ay
        s = ((px - ax) * ex + (py - ay) * ey) / (ex * ex + ey * ey)
        s = 0.0 if s < 0.0 else (1.0 if s > 1.0 else s)
        cx, cy = ax + s * ex, ay + s * ey
        d2 = (cx - px) ** 2 + (cy - py) ** 2
        if d2 < best[0]:
            best = (d2, cx, cy)
    return np.array([best[1], best[2]]), math.sqrt(best[0])


def soles_corners(
    positions: np.ndarray, yaws: np.ndarray, length: float, width: float
) -> np.ndarray:
    """(N, 4, 2) corners of N sole rectangles (centres ``positions`` (N, ≥2), ``yaws`` (N,) rad)."""
    positions = np.asarray(positions, dtype=float)
    yaws = np.asarray(yaws, dtype=float)
    local = _UNIT_CORNERS * [0.5 * length, 0.5 * width]  # (4, 2)
    c, s = np.cos(yaws)[:, None], np.sin(yaws)[:, None]
    x = positions[:, None, 0] + c * local[:, 0] - s * local[:, 1]
    y = positions[:, None, 1] + s * local[:, 0] + c * local[:, 1]
    return np.stack([x, y], axis=-1)


def hull_depth(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """How deep (m) each point lies inside the convex hull of its vertices; < 0 outside.

    ``points`` (N, 2), ``vertices`` (N, V, 2) (repeat vertices to pad).  Inside, the depth is the
    distance to the hull's boundary: the smallest signed distance to a supporting line through two
    vertices (one with every vertex on its left).  Outside it is negative and its magnitude at most
    the distance to the hull (equal unless the nearest hull point is a vertex).
    """
    points = np.asarray(points, dtype=float)
    vertices = np.asarray(vertices, dtype=float)
    n_vert = vertices.shape[1]
    i, j = np.nonzero(~np.eye(n_vert, dtype=bool))
    a = vertices[:, i]  # (N, P, 2) line start
    e = vertices[:, j] - a  # (N, P, 2) line direction
    length = np.hypot(e[..., 0], e[..., 1])
    valid = length > 1e-12
    safe = np.where(valid, length, 1.0)
    normal = np.stack([-e[..., 1], e[..., 0]], axis=-1) / safe[..., None]  # left of the line
    # signed distance of every vertex to every line: (N, P, V)
    rel = vertices[:, None, :, :] - a[:, :, None, :]
    side = np.einsum("npvk,npk->npv", rel, normal)
    supporting = valid & np.all(side >= -1e-9, axis=2)
    d = np.einsum("npk,npk->np", points[:, None, :] - a, normal)
    return np.min(np.where(supporting, d, np.inf), axis=1)


def rectangle_gap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Separation (m) of pairs of rectangles along their best separating axis; ≤ 0: they overlap.

    ``a``, ``b`` (N, 4, 2) corners in order (adjacent corners share an edge).  Separating-axis
    test over the edge normals of both rectangles; a positive gap is a lower bound of their
    distance (exact when an edge of one faces the other).
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    edges = np.concatenate([a[:, 1:3] - a[:, 0:2], b[:, 1:3] - b[:, 0:2]], axis=1)  # (N, 4, 2)
    axes = edges / np.linalg.norm(edges, axis=-1, keepdims=True)
    pa = np.einsum("nvk,nak->nav", a, axes)  # (N, axes, corners)
    pb = np.einsum("nvk,nak->nav", b, axes)
    gap = np.maximum(pb.min(-1) - pa.max(-1), pa.min(-1) - pb.max(-1))  # (N, axes)
    return gap.max(axis=1)
