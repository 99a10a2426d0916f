"""Click-to-push aim: each tab sees, beside the robot, the force a click would apply from its view.

A click on the robot pushes the clicked body along the *tab's* horizontal view direction (the
camera's look direction with its vertical part removed), with the magnitude and duration set in
the Push folder.  Every tab has its own camera, so each gets its own arrow through viser's
per-client scene (``client.scene``): an orange arrow on the ground, pointing along the push at the
point under the robot and stopping AIM_STANDOFF_M short of it (outside the feet), its length the
force at the scale of the applied-force arrows (NEWTONS_PER_METRE, at most AIM_MAX_LENGTH_M),
labelled with what a click does.  On the ground it points along the view without covering the
body one clicks.  The arrow hangs under one node placed under the robot, so following the robot
costs one small message per tab at FOLLOW_DT_S; its geometry is re-sent only when the view
turned by more than AIM_TURN_DEG or the force changed.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence

import numpy as np
import viser

from dcmviz.dashboard import scene as draw

AIM_COLOR = (255, 110, 0)
AIM_TURN_DEG = 2.0  # a view that turned less than this keeps its arrow
AIM_MOVE_M = 0.05  # the arrow follows the robot when it moved more than this
AIM_STANDOFF_M = 0.3  # the arrow's head stops this far before the point under the robot
AIM_MAX_LENGTH_M = 1.0  # longer arrows (above 100 N) are drawn this long; the label says |F|
AIM_LIFT_M = 0.015  # above the ground (over the footstep markers)
AIM_LABEL_LIFT_M = 0.08  # the label floats this far above the arrow's tail


def view_direction(camera: viser.CameraHandle) -> np.ndarray | None:
    """The camera's horizontal look direction (unit, z = 0); None when it looks straight down
    or up (no horizontal direction to push along)."""
    d = np.asarray(camera.look_at, float) - np.asarray(camera.position, float)
    d[2] = 0.0
    n = float(np.linalg.norm(d))
    return d / n if n > 1e-6 else None


def aim_points(direction: np.ndarray, magnitude: float) -> np.ndarray:
    """(1, 2, 3) arrow relative to the point under the robot: head AIM_STANDOFF_M before it,
    length magnitude / NEWTONS_PER_METRE (the applied-force arrows' scale), at most
    AIM_MAX_LENGTH_M."""
    tip = -AIM_STANDOFF_M * direction
    length = min(magnitude / draw.NEWTONS_PER_METRE, AIM_MAX_LENGTH_M)
    tail = tip - direction * length
    return np.array([[tail, tip]], np.float32) + np.float32(AIM_LIFT_M) * np.float32([0, 0, 1])


def describe(force: Sequence[float]) -> str:
    """'150 N toward +x (ψ_F = 0°)': a horizontal force's magnitude and direction."""
    fx, fy = float(force[0]), float(force[1])
    angle = math.degrees(math.atan2(fy, fx))
    names = ((0, "forward +x"), (90, "left +y"), (180, "backward −x"), (-90, "right −y"),
             (-180, "backward −x"))  # fmt: skip
    near = min(names, key=lambda n: abs(n[0] - angle))
    toward = f" ({near[1]})" if abs(near[0] - angle) <= 22.5 else ""
    return f"{math.hypot(fx, fy):.0f} N at ψ_F = {angle:.0f}°{toward}"


class _Aim:
    """One tab's arrow and label, and what they show."""

    def __init__(self, client: viser.ClientHandle) -> None:
        self.client = client
        self.root = client.scene.add_frame("/aim", show_axes=False, visible=False)
        self.arrow: viser.ArrowsHandle | None = None
        self.label: viser.LabelHandle | None = None
        self.shown: tuple[np.ndarray, float, str] | None = None  # direction, magnitude, text
        self.anchor: np.ndarray | None = None


class PushAim:
    """Keeps every tab's aim arrow in line with its camera, the Push folder and the robot."""

    def __init__(
        self,
        server: viser.ViserServer,
        force: Callable[[], tuple[float, float]],
    ) -> None:
        """``force()`` gives what a click applies now: (magnitude N, duration s)."""
        self.server = server
        self.force = force
        self._aims: dict[int, _Aim] = {}
        self._lock = threading.Lock()
        self._anchor: np.ndarray | None = None
        server.on_client_connect(self._connect)
        server.on_client_disconnect(self._disconnect)

    # -- what the dashboard calls -----------------------------------------------------------------
    def direction(self, client: viser.ClientHandle | None, fallback) -> np.ndarray:
        """The direction a click from ``client`` pushes along: its horizontal view, or
        ``fallback`` (the click ray) where the view has none."""
        d = view_direction(client.camera) if client is not None else None
        return d if d is not None else np.asarray(fallback, float)  # (horizontal_force levels it)

    def follow(self, anchor: np.ndarray | None) -> None:
        """Place every tab's arrow at ``anchor`` (the ground point under the robot; None hides
        them)."""
        with self._lock:
            self._anchor = None if anchor is None else np.asarray(anchor, float).copy()
        self.refresh()

    def refresh(self) -> None:
        """The force a click applies changed: redraw every tab's arrow."""
        connected = self.server.get_clients()  # (a closing tab may not be disconnected yet)
        with self._lock:
            aims = [a for cid, a in self._aims.items() if cid in connected]
        for aim in aims:
            self._draw(aim)

    def shown(self, client_id: int) -> tuple[np.ndarray, float, str] | None:
        """What tab ``client_id``'s arrow shows: (direction, magnitude, label) or None."""
        aim = self._aims.get(client_id)
        return None if aim is None else aim.shown

    def world_points(self, client_id: int) -> np.ndarray | None:
        """(2, 3) tail and head of tab ``client_id``'s arrow in the world, or None."""
        aim = self._aims.get(client_id)
        if aim is None or aim.shown is None or aim.anchor is None:
            return None
        return aim.anchor + aim_points(aim.shown[0], aim.shown[1])[0].astype(float)

    # -- internals --------------------------------------------------------------------------------
    def _connect(self, client: viser.ClientHandle) -> None:
        aim = _Aim(client)
        with self._lock:
            self._aims[client.client_id] = aim
        client.camera.on_update(lambda _camera: self._draw(aim))
        self._draw(aim)

    def _disconnect(self, client: viser.ClientHandle) -> None:
        with self._lock:
            self._aims.pop(client.client_id, None)

    def _draw(self, aim: _Aim) -> None:
        with self._lock:
            anchor = self._anchor
            if aim.client.client_id not in self._aims:
                return  # closed
            try:
                self._draw_locked(aim, anchor)
            except Exception:  # noqa: BLE001 - a tab that just closed
                pass

    def _draw_locked(self, aim: _Aim, anchor: np.ndarray | None) -> None:
        direction = view_direction(aim.client.camera)
        if anchor is None or direction is None:
            aim.root.visible = False
            return
        if aim.anchor is None or float(np.abs(aim.anchor - anchor).max()) > AIM_MOVE_M:
            aim.root.position = anchor
            aim.anchor = anchor
        magnitude, duration = self.force()
        text = f"click: {magnitude:.0f} N for {duration:.2f} s"
        old = aim.shown
        turned = (
            old is None
            or float(np.clip(old[0] @ direction, -1.0, 1.0)) < math.cos(math.radians(AIM_TURN_DEG))
            or old[1] != magnitude
        )
        points = aim_points(direction, magnitude)
        if turned:
            if aim.arrow is None:
                aim.arrow = aim.client.scene.add_arrows(
                    "/aim/arrow", points, AIM_COLOR,
                    shaft_radius=0.01, head_radius=0.035, head_length=0.07,
                )  # fmt: skip
            else:
                aim.arrow.points = points
        if turned or old[2] != text:
            position = points[0, 0] + np.array([0.0, 0.0, AIM_LABEL_LIFT_M], np.float32)
            if aim.label is None:
                aim.label = aim.client.scene.add_label("/aim/label", text, position=position)
            else:
                aim.label.text = text
                aim.label.position = position
            aim.shown = (direction, magnitude, text)
        aim.root.visible = True
