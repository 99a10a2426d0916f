"""Panel plots (uPlot): the preview's VRP and DCM over time (the paper's Fig. 1a) and the live
measured / reference / adjusted DCM of the simulation."""

from __future__ import annotations

import numpy as np
import viser
import viser.uplot as uplot

from dcmviz.dashboard.preview import PHASE_COLORS, PreviewData
from dcmviz.session.signals import SIGNALS

AXES = ("x", "y", "z")
VRP_STROKE = "#f08c1e"
DCM_STROKE = SIGNALS["dcm"].hex
MEASURED_STROKE = SIGNALS["xi"].hex
REF_STROKE = SIGNALS["xi_ref"].hex
ADJ_STROKE = SIGNALS["xi_adj"].hex
ERROR_STROKE = SIGNALS["dcm_error"].hex
LIVE_POINTS = 200  # samples per live series (8 s in a 400 px wide panel: 25 a second)
PREVIEW_POINTS = 250  # samples per preview series
PLOT_TOLERANCE = 2e-3  # m (and s): a preview plot whose samples all moved less is not re-sent


def thin(n: int, points: int) -> slice:
    """Every k-th of ``n`` samples so that at most about ``points`` remain (the last kept)."""
    return slice(None, None, max(1, -(-n // points)))


def f32(x: np.ndarray, every: slice) -> np.ndarray:
    """Samples as float32: half the bytes of float64 in a message that goes to every tab."""
    return np.ascontiguousarray(np.asarray(x)[every], np.float32)


def _series(label: str, stroke: str, dash: list[float] | None = None) -> uplot.Series:
    s: dict = {"label": label, "stroke": stroke, "width": 2}
    if dash:
        s["dash"] = dash
    return s  # type: ignore[return-value]


def _axes(y_label: str) -> tuple[uplot.Axis, uplot.Axis]:
    return ({"label": "t [s]", "size": 30}, {"label": y_label, "size": 48})  # type: ignore[return-value]


class PreviewPlots:
    """Three uPlots (x, y, z): VRP v(t) and DCM ξ(t) of the preview, eqs. (13), (16)."""

    def __init__(self, gui: viser.GuiApi) -> None:
        empty = (np.zeros(2), np.zeros(2), np.zeros(2))
        self.handles = [
            gui.add_uplot(
                empty,
                (
                    {"label": "t"},
                    _series(f"v_{a}", VRP_STROKE),
                    _series(f"ξ_{a}", DCM_STROKE),
                ),
                title=f"preview {a} [m]",
                axes=_axes(f"{a} [m]"),
                scales={"x": {"time": False}},  # type: ignore[dict-item]
                height=150,
            )
            for a in AXES
        ]

    def draw(self, data: PreviewData) -> None:
        """Replace the data of the three plots (each only if it changed by more than
        PLOT_TOLERANCE, far below a pixel: a touchdown moves the walked plan by ~1 mm)."""
        every = thin(len(data.t), PREVIEW_POINTS)
        t = f32(data.t, every)
        for i, handle in enumerate(self.handles):
            new = (t, f32(data.vrp[:, i], every), f32(data.dcm[:, i], every))
            old = handle.data
            if len(old) == 3 and all(
                np.shape(a) == b.shape
                and (b.size == 0 or float(np.abs(np.asarray(a) - b).max()) <= PLOT_TOLERANCE)
                for a, b in zip(old, new, strict=True)
            ):
                continue
            handle.data = new


class LivePlot:
    """Measured vs reference vs adjusted DCM along one axis, and the DCM error norm."""

    def __init__(self, gui: viser.GuiApi, axis: str = "y") -> None:
        self.axis = axis
        empty = (np.zeros(2),) * 4
        self.dcm = gui.add_uplot(
            empty,
            (
                {"label": "t"},
                _series("ξ", MEASURED_STROKE),
                _series("ξ_ref", REF_STROKE, [6, 4]),
                _series("ξ_adj", ADJ_STROKE),
            ),
            title=f"DCM {axis} [m]",
            axes=_axes(f"ξ_{axis} [m]"),
            scales={"x": {"time": False}},  # type: ignore[dict-item]
            height=160,
        )
        self.error = gui.add_uplot(
            (np.zeros(2), np.zeros(2)),
            ({"label": "t"}, _series("|ξ − ξ_ref|", ERROR_STROKE)),
            title="DCM error [m]",
            axes=_axes("[m]"),
            scales={"x": {"time": False}},  # type: ignore[dict-item]
            height=120,
        )

    def set_axis(self, axis: str) -> None:
        self.axis = axis
        self.dcm.title = f"DCM {axis} [m]"

    def draw(self, history: dict[str, np.ndarray]) -> None:
        """Plot the history window (arrays of equal length; t plus (N, 3) DCMs and (N,) error)."""
        t = history.get("t")
        if t is None or len(t) < 2:
            return
        i = AXES.index(self.axis)
        every = thin(len(t), LIVE_POINTS)
        t = f32(t, every)
        self.dcm.data = (t, *(f32(history[k][:, i], every) for k in ("xi", "xi_ref", "xi_adj")))
        self.error.data = (t, f32(history["dcm_error"], every))


def phase_legend() -> str:
    """Markdown: the VRP colour of each phase kind, and the DCM's."""
    items = [
        f"<span style='color:rgb({r},{g},{b})'>■</span> {kind}"
        for kind, (r, g, b) in PHASE_COLORS.items()
    ]
    return (
        "<small>VRP by phase: "
        + " ".join(items)
        + f" · <span style='color:{DCM_STROKE}'>━</span> DCM"
        "</small>"
    )
