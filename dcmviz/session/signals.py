"""The signals of a tick: their names, symbols and one colour each, for every shell that shows them
(the dashboard's scene and plots, the rerun recording, the runner's CSV columns)."""

from __future__ import annotations

from dataclasses import dataclass

RGB = tuple[int, int, int]


@dataclass(frozen=True)
class Signal:
    key: str  # the WalkerCommand / Tick / CSV name
    symbol: str  # as the paper writes it
    description: str
    color: RGB

    @property
    def hex(self) -> str:
        """``#rrggbb`` for HTML and plot strokes."""
        return "#{:02x}{:02x}{:02x}".format(*self.color)


SIGNALS: dict[str, Signal] = {
    s.key: s
    for s in (
        Signal("xi", "ξ", "measured DCM (eq. 1)", (0, 170, 255)),
        Signal("xi_ref", "ξ_ref", "DCM reference (eqs. 20, 48)", (68, 68, 68)),
        Signal("xi_adj", "ξ_adj", "adapted DCM reference (eqs. 33, 49)", (255, 0, 200)),
        Signal("v_ref", "v_ref", "VRP reference (eq. 47)", (240, 140, 30)),
        Signal("v_cmd", "v_cmd", "commanded VRP (eqs. 24, 41)", (255, 200, 0)),
        Signal("com", "x", "measured CoM", (120, 120, 130)),
        Signal("f_ext", "F_ext", "applied external force", (230, 30, 30)),
        Signal("f_hat", "F̂", "observer's estimate of the external force (eq. 45)", (30, 170, 60)),
        Signal("dcm", "ξ_ref(t)", "previewed DCM (closed form, eqs. 5–23)", (30, 60, 200)),
        Signal("dcm_error", "|ξ − ξ_ref|", "DCM tracking error", (214, 39, 40)),
    )
}

# footsteps: as planned, adjusted (the adapted reference's footholds) and where the feet landed
FOOTSTEP_COLORS: dict[str, RGB] = {
    "planned": (170, 170, 170),
    "adjusted": SIGNALS["xi_adj"].color,
    "realised": (60, 60, 60),
}
SIDE_COLORS: dict[str, RGB] = {"left": (70, 130, 230), "right": (225, 80, 80)}
TERRAIN_COLOR: RGB = (168, 158, 140)  # stone; distinct from the floor, the soles and the robot


def color(key: str) -> RGB:
    """The colour of signal ``key``."""
    return SIGNALS[key].color
