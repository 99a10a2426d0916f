"""``draw_*`` functions: each re-adds its scene nodes at stable paths, so redrawing is idempotent.

They read state (a :class:`PreviewData`, a :class:`~dcmviz.dashboard.loop.Snapshot`) and never
compute anything beyond turning it into geometry.  A node whose geometry is within
PREVIEW_TOLERANCE_M of what it already shows (same style) is not sent again: every write goes to
every tab, and a touchdown that commits a footstep moves the walked plan by about a millimetre.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence

import numpy as np
import viser

from dcmviz.dashboard.preview import PreviewData, Sole
from dcmviz.session.signals import FOOTSTEP_COLORS, SIDE_COLORS, SIGNALS
from dcmviz.session.signals import color as signal_color

DCM_COLOR = signal_color("dcm")
VRP_WAYPOINT_COLOR = (20, 20, 20)
MEASURED_DCM_COLOR = signal_color("xi")
ADJUSTED_DCM_COLOR = signal_color("xi_adj")
COMMANDED_VRP_COLOR = signal_color("v_cmd")
FORCE_COLOR = signal_color("f_ext")
OBSERVER_COLOR = signal_color("f_hat")
GHOST_COLOR = FOOTSTEP_COLORS["adjusted"]
COP_COLOR = (140, 86, 75)  # measured centre of pressure and contact forces
KEPT_COLOR = (150, 150, 150)  # the kept preview A (A/B comparison)
FRAME_LOOK_AT_HEIGHT_M = 0.55  # "Frame robot": look at this height above the robot's ground
FRAME_OFFSET = np.array([3.4, 1.4, 1.8])  # … from this far (front-left, above: the floor
# around the feet shows, as in the first view)
# "Frame robot" looks at a point this far (x, y) to the right of the robot (1.2 m along the
# view's right): the canvas spans the page right of the plot panel and the control panel floats
# over its right third, so the robot is drawn in the middle of what is free
_RIGHT = np.cross(-FRAME_OFFSET, [0.0, 0.0, 1.0])[:2]
FRAME_SHIFT = 1.2 * _RIGHT / np.linalg.norm(_RIGHT)
FIRST_LOOK_AT = np.array([0.56, 0.87])  # the first view's (the walk's first metres in the
# free part)
REALISED_COLOR = FOOTSTEP_COLORS["realised"]
SWING_COLOR = ADJUSTED_DCM_COLOR  # the swinging sole's path, to the footstep it lands on
SOLE_THICKNESS_M = 0.006
NEWTONS_PER_METRE = 100.0  # arrow length scale: 100 N ↔ 1 m
SPLINE_POINTS = 150  # control points of the DCM splines (Catmull-Rom: smooth between them)
VRP_SEGMENT_STRIDE = 2  # preview samples per drawn VRP segment (divides SAMPLES_PER_PHASE)
ARROW_STANDOFF_M = 0.15  # a push arrow stops this far before the body point (outside the shell)
# geometry that moved less than this is not re-sent (about half a pixel at 3 m; a touchdown moves
# the walked plan's committed footstep and its waypoints by ~1.3 mm)
PREVIEW_TOLERANCE_M = 2e-3

# per scene: node name → (arrays, style) it shows
_drawn: weakref.WeakKeyDictionary[viser.SceneApi, dict[str, tuple]] = weakref.WeakKeyDictionary()


def shown(scene: viser.SceneApi, name: str, arrays: Sequence[np.ndarray], style: tuple) -> bool:
    """True if node ``name`` already shows ``arrays`` (each within PREVIEW_TOLERANCE_M, same
    shapes) in ``style``; otherwise remember them as shown (the caller then draws them)."""
    drawn = _drawn.setdefault(scene, {})
    arrays = tuple(np.asarray(a) for a in arrays)
    old = drawn.get(name)
    if (
        old is not None
        and old[1] == style
        and len(old[0]) == len(arrays)
        and all(
            a.shape == b.shape
            and (a.size == 0 or float(np.abs(a - b).max()) <= PREVIEW_TOLERANCE_M)
            for a, b in zip(old[0], arrays, strict=True)
        )
    ):
        return True
    drawn[name] = (tuple(a.copy() for a in arrays), style)
    return False


def forget(scene: viser.SceneApi, prefix: str) -> None:
    """Nodes under ``prefix`` were removed or replaced elsewhere: draw them afresh next time."""
    drawn = _drawn.get(scene, {})
    for name in [n for n in drawn if n.startswith(prefix)]:
        drawn.pop(name, None)


def soles_mesh(
    soles: Sequence[Sole], length: float, width: float, lift: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (8n, 3) and faces (12n, 3) of thin boxes, one per sole."""
    if not soles:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint32)
    box_faces = np.array(
        [
            [0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6],  # top, bottom
            [0, 4, 5], [0, 5, 1], [1, 5, 6], [1, 6, 2],
            [2, 6, 7], [2, 7, 3], [3, 7, 4], [3, 4, 0],
        ]
    )  # fmt: skip
    verts, faces = [], []
    for i, sole in enumerate(soles):
        top = sole.corners(length, width) + [0.0, 0.0, lift + SOLE_THICKNESS_M]
        bottom = top - [0.0, 0.0, SOLE_THICKNESS_M]
        verts.append(np.vstack([top, bottom]))
        faces.append(box_faces + 8 * i)
    return np.vstack(verts).astype(np.float32), np.vstack(faces).astype(np.uint32)


def _draw_soles(
    scene: viser.SceneApi,
    name: str,
    soles: Sequence[Sole],
    length: float,
    width: float,
    color: tuple[int, int, int],
    opacity: float = 1.0,
    lift: float = 0.0,
) -> None:
    if not soles:
        if not shown(scene, name, (), ("empty",)):
            scene.add_frame(name, show_axes=False)  # replaces the node: nothing drawn
        return
    v, f = soles_mesh(soles, length, width, lift)
    if shown(scene, name, (v, f), ("soles", color, opacity)):
        return
    scene.add_mesh_simple(
        name, v, f, color=color, opacity=opacity if opacity < 1.0 else None, flat_shading=True
    )


def draw_footsteps(scene: viser.SceneApi, data: PreviewData) -> None:
    """The planned soles as rectangles, blue left / red right, paler for the standing feet."""
    for side in ("left", "right"):
        planned = [s for s in data.soles if s.side == side and s.index >= 0]
        standing = [s for s in data.soles if s.side == side and s.index < 0]
        _draw_soles(
            scene, f"/preview/soles/{side}", planned, data.foot_length, data.foot_width,
            SIDE_COLORS[side], opacity=0.7,
        )  # fmt: skip
        _draw_soles(
            scene, f"/preview/soles/{side}_start", standing, data.foot_length, data.foot_width,
            SIDE_COLORS[side], opacity=0.3,
        )  # fmt: skip


def thin_segments(
    pts: np.ndarray, colors: np.ndarray, stride: int
) -> tuple[np.ndarray, np.ndarray]:
    """Join each ``stride`` consecutive segments of a polyline into one (the colour of the
    first): with ``stride`` dividing the samples per phase, phase boundaries stay vertices."""
    if stride <= 1 or len(pts) <= stride:
        return pts, colors
    starts = pts[::stride, 0]
    ends = np.vstack([starts[1:], pts[-1:, 1]])
    return np.stack([starts, ends], axis=1).astype(np.float32), colors[::stride]


def draw_preview(scene: viser.SceneApi, data: PreviewData) -> None:
    """VRP trajectory coloured by phase kind, its waypoints, and the DCM trajectory (eqs. 13, 16)."""
    pts, colors = data.vrp_segments()
    pts, colors = thin_segments(pts, colors, VRP_SEGMENT_STRIDE)
    if not shown(scene, "/preview/vrp", (pts, colors), ("vrp",)):
        scene.add_line_segments(
            "/preview/vrp", pts, colors, thickness=4.0, thickness_units="screen"
        )
    waypoints = data.waypoints.astype(np.float32)
    if not shown(scene, "/preview/vrp_waypoints", (waypoints,), ("waypoints",)):
        scene.add_point_cloud(
            "/preview/vrp_waypoints",
            waypoints,
            colors=VRP_WAYPOINT_COLOR,
            point_size=0.03,
            point_shape="circle",
        )
    dcm = data.dcm[:: max(1, len(data.dcm) // SPLINE_POINTS)].astype(np.float32)
    if not shown(scene, "/preview/dcm", (dcm,), ("dcm",)):
        scene.add_spline_catmull_rom(
            "/preview/dcm", dcm, color=DCM_COLOR, thickness=3.0, thickness_units="screen"
        )
    # the ground projection of the DCM helps reading it against the footsteps
    ground = dcm.copy()
    ground[:, 2] = data.soles[0].position[2] + 0.003 if data.soles else 0.003
    if not shown(scene, "/preview/dcm_ground", (ground,), ("dcm_ground",)):
        scene.add_spline_catmull_rom(
            "/preview/dcm_ground", ground, color=(150, 160, 220),
            thickness=2.0, thickness_units="screen",
        )  # fmt: skip


def draw_kept(scene: viser.SceneApi, data: PreviewData | None) -> None:
    """The kept preview A (grey): its DCM, its VRP and its footsteps, to compare the preview
    drawn now against (None removes it)."""
    if data is None:
        if not shown(scene, "/kept", (), ("empty",)):
            scene.add_frame("/kept", show_axes=False)  # replaces the node and its children
            forget(scene, "/kept/")
        return
    shown(scene, "/kept", (), ("kept",))
    dcm = data.dcm[:: max(1, len(data.dcm) // SPLINE_POINTS)].astype(np.float32)
    if not shown(scene, "/kept/dcm", (dcm,), ("dcm",)):
        scene.add_spline_catmull_rom(
            "/kept/dcm", dcm, color=KEPT_COLOR, thickness=3.0, thickness_units="screen"
        )
    vrp = data.vrp[:: max(1, len(data.vrp) // SPLINE_POINTS)].astype(np.float32)
    if not shown(scene, "/kept/vrp", (vrp,), ("vrp",)):
        scene.add_spline_catmull_rom(
            "/kept/vrp", vrp, color=(190, 190, 190), thickness=2.0, thickness_units="screen"
        )
    soles = [s for s in data.soles if s.index >= 0]
    _draw_soles(scene, "/kept/soles", soles, data.foot_length, data.foot_width, KEPT_COLOR,
                opacity=0.35, lift=0.002)  # fmt: skip


WARNING_COLOR = (230, 20, 20)


def draw_warnings(
    scene: viser.SceneApi, soles: Sequence[Sole], waypoints: np.ndarray, length: float,
    width: float,
) -> None:  # fmt: skip
    """Red outlines around the footsteps and red spheres on the VRP waypoints a feasibility
    warning names (an empty frame when there are none, so the last marks disappear)."""
    if len(soles):
        segments = []
        for sole in soles:
            c = sole.corners(length * 1.15, width * 1.3) + [0.0, 0.0, 0.015]
            segments += [[c[i], c[(i + 1) % 4]] for i in range(4)]
        segments = np.array(segments, np.float32)
        if not shown(scene, "/preview/warnings/steps", (segments,), ("warnings",)):
            scene.add_line_segments(
                "/preview/warnings/steps", segments, WARNING_COLOR,
                thickness=5.0, thickness_units="screen",
            )  # fmt: skip
    elif not shown(scene, "/preview/warnings/steps", (), ("empty",)):
        scene.add_frame("/preview/warnings/steps", show_axes=False)
    if len(waypoints):
        points = np.asarray(waypoints, np.float32)
        if not shown(scene, "/preview/warnings/waypoints", (points,), ("warnings",)):
            scene.add_point_cloud(
                "/preview/warnings/waypoints", points,
                colors=WARNING_COLOR, point_size=0.07, point_shape="circle",
            )  # fmt: skip
    elif not shown(scene, "/preview/warnings/waypoints", (), ("empty",)):
        scene.add_frame("/preview/warnings/waypoints", show_axes=False)


def draw_step_markers(
    scene: viser.SceneApi, name: str, soles: Sequence[Sole], length: float, width: float,
    color: tuple[int, int, int], opacity: float, lift: float,
) -> None:  # fmt: skip
    """Adjusted (ghost) or realised footsteps from the simulation."""
    _draw_soles(scene, name, soles, length, width, color, opacity=opacity, lift=lift)


# what the colours mean (markdown above the panel's tabs: always in sight)
SCENE_LEGEND = (
    "<small>Dots on pins above their ground points (Δz_vrp below the CoM): "
    f"<span style='color:{SIGNALS['xi'].hex}'>●</span> ξ · "
    f"<span style='color:{SIGNALS['xi_adj'].hex}'>●</span> ξ_adj · "
    f"<span style='color:{SIGNALS['v_cmd'].hex}'>●</span> v_cmd · "
    "<span style='color:#8c564b'>●↑</span> measured CoP, contact forces · "
    f"<span style='color:{SIGNALS['f_ext'].hex}'>→</span> F_ext (push, drag) · "
    f"<span style='color:{SIGNALS['f_hat'].hex}'>→</span> F̂ (observer, above the head). "
    "Footsteps: "
    f"<span style='color:{SIGNALS['xi_adj'].hex}'>▭</span> adjusted · "
    "<span style='color:#3c3c3c'>▬</span> realised · "
    "<span style='color:#969696'>▭</span> kept preview A.</small>"
)


GRID_SIZE_M = 40.0  # the floor grid's side: it moves under the robot in whole metres
GRID_RECENTRE_M = 8.0  # ... once the robot is this far from its centre


class Ground:
    """The floor grid, a finite square that moves under a robot walking off it, whole metres
    at a time (its lines stay where they were).  Not viser's infinite grid: its full-screen
    shader made headless Chromium's software WebGL draw a frame in ~320 ms instead of ~130 ms
    (bench/dashboard.py --latency, Talos at 1600 × 900), and every change in the page waits for
    a frame."""

    def __init__(self, scene: viser.SceneApi) -> None:
        self.centre = np.zeros(2)
        self.handle = scene.add_grid(
            "/grid", width=GRID_SIZE_M, height=GRID_SIZE_M, cell_size=0.1, section_size=1.0,
            plane="xy", position=(0.0, 0.0, -0.001), cell_color=(220, 220, 220),
            section_color=(170, 170, 170), infinite_grid=False, fade_distance=30.0,
        )  # fmt: skip

    def follow(self, point: np.ndarray | None) -> None:
        """Re-centre the grid under ``point`` (m, world) once it is GRID_RECENTRE_M away."""
        if point is None:
            return
        xy = np.asarray(point, float)[:2]
        if np.abs(xy - self.centre).max() < GRID_RECENTRE_M:
            return
        self.centre = np.round(xy)
        self.handle.position = (float(self.centre[0]), float(self.centre[1]), -0.001)


def draw_ground(server: viser.ViserServer) -> Ground:
    """Floor grid, lights and the initial camera (in front of the walk); returns the grid."""
    scene = server.scene
    scene.set_up_direction("+z")
    ground = Ground(scene)
    # no HDR environment map: while a browser decodes one (seconds in software WebGL) viser
    # draws the whole scene at 5 % opacity, so a newcomer would first see a washed-out robot
    scene.configure_environment_map(hdri=None)
    # viser's default lights cast shadows: a shadow pass per frame made headless Chromium's
    # software WebGL draw one frame in ~850 ms (bench/dashboard.py --latency: Talos at
    # 1600 × 900), and every change in the page waited for it; the two lights below light the
    # scene without shadows (a GPU draws either at 60 frames a second)
    scene.configure_default_lights(enabled=False)
    scene.add_light_hemisphere("/light/sky", intensity=1.6)
    scene.add_light_directional("/light/sun", intensity=2.2, position=(4.0, 2.0, 5.0))
    camera = server.initial_camera
    # in front of the walk, slightly to its left: the robot walks towards the viewer through
    # the middle of the view, between the plot panel (left) and the control panel (right)
    # (the canvas spans everything right of the plot panel; the control panel floats over its
    # right third, so the view is shifted ~0.9 m sideways to centre the walk in the free part)
    look_at = np.array([*FIRST_LOOK_AT, FRAME_LOOK_AT_HEIGHT_M])
    camera.position = tuple(look_at + FRAME_OFFSET)  # high enough to see the floor by the feet
    camera.look_at = tuple(look_at)
    return ground
