"""The terrain in the 3-D scene: one viser box per block of the preset's ``[terrain]``.

Drawn at stable paths ``/terrain/<i>`` (idempotent); a preset with fewer boxes (or none) removes
the ones left over.  Both backends walk the same terrain, so it is drawn for either.
"""

from __future__ import annotations

import math

import viser

from dcmviz.config import Config
from dcmviz.gait.terrain import Terrain, terrain_of
from dcmviz.session.signals import TERRAIN_COLOR


class TerrainView:
    """Draws a config's terrain, redrawing only when it changes."""

    def __init__(self, scene: viser.SceneApi) -> None:
        self.scene = scene
        self.terrain: Terrain | None = None
        self.handles: list[viser.BoxHandle] = []

    def show(self, config: Config) -> None:
        terrain = terrain_of(config.terrain)
        if terrain == self.terrain:
            return
        self.terrain = terrain
        draw_terrain(self.scene, terrain, self.handles)


def draw_terrain(scene: viser.SceneApi, terrain: Terrain, handles: list[viser.BoxHandle]) -> None:
    """Boxes from the floor to each top face at ``/terrain/<i>``; ``handles`` (the boxes drawn
    before) is updated in place: extra ones are removed."""
    for i, box in enumerate(terrain.boxes):
        centre, half = box.solid
        handle = scene.add_box(
            f"/terrain/{i}",
            color=TERRAIN_COLOR,
            dimensions=tuple(float(2 * h) for h in half),
            position=tuple(float(c) for c in centre),
            wxyz=(math.cos(0.5 * box.yaw), 0.0, 0.0, math.sin(0.5 * box.yaw)),
        )
        if i < len(handles):
            handles[i] = handle
        else:
            handles.append(handle)
    for handle in handles[len(terrain.boxes) :]:
        handle.remove()
    del handles[len(terrain.boxes) :]
