"""Panel plots (uPlot): the preview's VRP and DCM over time (the paper's Fig. 1a), with a kept
preview (A) to compare against, and the live signals of the simulation, chosen by the user."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import viser
import viser.uplot as uplot

from dcmviz.dashboard.preview import PHASE_COLORS, PreviewData
from dcmviz.session.signals import SIGNALS

AXES = ("x", "y", "z")
VRP_STROKE = "#f08c1e"
DCM_STROKE = SIGNALS["dcm"].hex
GHOST_STROKE = "#9a9a9a"  # the kept preview (A) and its footsteps: grey
ERROR_STROKE = SIGNALS["dcm_error"].hex
COP_STROKE = "#8c564b"
LIVE_POINTS = 300  # samples per live series
PREVIEW_POINTS = 250  # samples per preview series
PLOT_TOLERANCE = 2e-3  # m (and s): a preview plot whose samples all moved less is not re-sent

# the live plot's signals: key in the plot window → (label, stroke, scale, dash, shown at first)
LIVE_SIGNALS: dict[str, tuple[str, str, str, list[float] | None, bool]] = {
    "xi": ("ξ", SIGNALS["xi"].hex, "m", None, True),
    "xi_ref": ("ξ_ref", SIGNALS["xi_ref"].hex, "m", [6, 4], True),
    "xi_adj": ("ξ_adj", SIGNALS["xi_adj"].hex, "m", None, True),
    "v_cmd": ("v_cmd", SIGNALS["v_cmd"].hex, "m", None, False),
    "com": ("CoM x", SIGNALS["com"].hex, "m", None, False),
    "cop": ("CoP", COP_STROKE, "m", None, False),
    "f_hat": ("F̂", SIGNALS["f_hat"].hex, "N", None, False),
    "f_ext": ("F_ext", SIGNALS["f_ext"].hex, "N", None, False),
}


def thin(n: int, points: int) -> slice:
    """Every k-th of ``n`` samples so that at most about ``points`` remain, counted from the
    end: the last sample (the frame shown) is always kept."""
    k = max(1, -(-n // points))
    return slice((n - 1) % k, None, k)


def f32(x: np.ndarray, every: slice) -> np.ndarray:
    """Samples as float32: half the bytes of float64 in a message that goes to every tab."""
    return np.ascontiguousarray(np.asarray(x)[every], np.float32)


def preview_series(
    data: PreviewData, ghost: PreviewData | None, dtype: type = np.float64
) -> tuple[np.ndarray, list[tuple[np.ndarray, ...]]]:
    """Fig. 1a's samples: the times (at most about PREVIEW_POINTS, the last kept) and per axis
    (x, y, z) the VRP and DCM there, and A's (``ghost``) on the same times (outside A's: its
    ends held) when there is one."""
    every = thin(len(data.t), PREVIEW_POINTS)
    t = np.ascontiguousarray(np.asarray(data.t)[every], dtype)
    axes = []
    for i in range(len(AXES)):
        series = [np.ascontiguousarray(data.vrp[every, i], dtype),
                  np.ascontiguousarray(data.dcm[every, i], dtype)]  # fmt: skip
        if ghost is not None:
            series += [np.interp(t, ghost.t, ghost.vrp[:, i]).astype(dtype),
                       np.interp(t, ghost.t, ghost.dcm[:, i]).astype(dtype)]  # fmt: skip
        axes.append(tuple(series))
    return t, axes


def moved(old: tuple[np.ndarray, ...], new: tuple[np.ndarray, ...]) -> bool:
    """True unless ``new`` has ``old``'s shapes and no sample moved by more than PLOT_TOLERANCE."""
    return len(old) != len(new) or any(
        a.shape != b.shape or (b.size > 0 and float(np.abs(a - b).max()) > PLOT_TOLERANCE)
        for a, b in zip(old, new, strict=True)
    )


def _series(label: str, stroke: str, dash: list[float] | None = None, **extra) -> uplot.Series:
    s: dict = {"label": label, "stroke": stroke, "width": 2, **extra}
    if dash:
        s["dash"] = dash
    return s  # type: ignore[return-value]


def _axes(y_label: str) -> tuple[uplot.Axis, uplot.Axis]:
    return ({"label": "t [s]", "size": 30}, {"label": y_label, "size": 48})  # type: ignore[return-value]


class PreviewPlots:
    """Three uPlots (x, y, z): VRP v(t) and DCM ξ(t) of the preview, eqs. (13), (16), and those
    of the kept preview A (grey, dashed) when there is one."""

    def __init__(self, gui: viser.GuiApi) -> None:
        empty = (np.zeros(2),) * 5
        self.ghost: PreviewData | None = None
        self.handles = [
            gui.add_uplot(
                empty,
                self._series_of(a, False),
                title=f"preview {a} [m]",
                axes=_axes(f"{a} [m]"),
                scales={"x": {"time": False}},  # type: ignore[dict-item]
                height=150,
            )
            for a in AXES
        ]
        self._data: PreviewData | None = None

    @staticmethod
    def _series_of(axis: str, ghost: bool) -> tuple:
        return (
            {"label": "t"},
            _series(f"v_{axis}", VRP_STROKE),
            _series(f"ξ_{axis}", DCM_STROKE),
            _series(f"A: v_{axis}", GHOST_STROKE, [4, 4], show=ghost),
            _series(f"A: ξ_{axis}", GHOST_STROKE, [10, 4], show=ghost),
        )

    def set_ghost(self, ghost: PreviewData | None) -> None:
        """Compare against ``ghost`` (None: no comparison) from the next draw on."""
        self.ghost = ghost
        for axis, handle in zip(AXES, self.handles, strict=True):
            handle.series = self._series_of(axis, ghost is not None)
        if self._data is not None:
            self.draw(self._data, force=True)

    def draw(self, data: PreviewData, force: bool = False) -> None:
        """Replace the data of the three plots (each only if it changed by more than
        PLOT_TOLERANCE, far below a pixel: a touchdown moves the walked plan by ~1 mm)."""
        self._data = data
        t, axes = preview_series(data, self.ghost, np.float32)
        for handle, (v, xi, *kept) in zip(self.handles, axes, strict=True):
            new = (t, v, xi, *(kept or (v, xi)))  # A's series hidden: B's numbers
            old = handle.data
            if not force and len(old) == 5 and not moved(tuple(map(np.asarray, old)), new):
                continue
            handle.data = new


class LivePlot:
    """The simulation's signals along one axis over a window before the frame shown (the user
    picks which), and the DCM error norm."""

    def __init__(self, gui: viser.GuiApi, axis: str = "y") -> None:
        self.axis = axis
        self.shown = {key: spec[4] for key, spec in LIVE_SIGNALS.items()}
        self.history: dict[str, np.ndarray] = {}
        empty = (np.zeros(2),) * (1 + len(LIVE_SIGNALS))
        self.signals = gui.add_uplot(
            empty,
            self._series(),
            title=f"signals {axis}",
            axes=(
                {"label": "t [s]", "size": 30},
                {"label": f"{axis} [m]", "size": 48, "scale": "m"},
                {"label": "[N]", "size": 40, "scale": "N", "side": 1, "grid": {"show": False}},
            ),  # type: ignore[arg-type]
            scales={"x": {"time": False}, "m": {"auto": True}, "N": {"auto": True}},  # type: ignore[dict-item]
            height=190,
        )
        self.error = gui.add_uplot(
            (np.zeros(2), np.zeros(2)),
            ({"label": "t"}, _series("|ξ − ξ_ref|", ERROR_STROKE)),
            title="DCM error [m]",
            axes=_axes("[m]"),
            scales={"x": {"time": False}},  # type: ignore[dict-item]
            height=120,
        )

    def _series(self) -> tuple:
        out: list = [{"label": "t"}]
        for key, (label, stroke, scale, dash, _) in LIVE_SIGNALS.items():
            name = label if key != "com" else "CoM"
            out.append(_series(name, stroke, dash, scale=scale, show=self.shown[key]))
        return tuple(out)

    def set_axis(self, axis: str) -> None:
        self.axis = axis
        self.signals.title = f"signals {axis}"
        self.draw(self.history)

    def show(self, key: str, shown: bool) -> None:
        """Show or hide one signal."""
        self.shown[key] = bool(shown)
        self.signals.series = self._series()

    def draw(self, history: dict[str, np.ndarray]) -> None:
        """Plot a plot window (``t`` plus (N, 3) signals and the (N,) error)."""
        self.history = history
        t = history.get("t")
        if t is None or len(t) < 2:
            return
        i = AXES.index(self.axis)
        every = thin(len(t), LIVE_POINTS)
        ts = f32(t, every)
        columns = []
        for key in LIVE_SIGNALS:
            values = history.get(key)
            columns.append(f32(values[:, i], every) if values is not None else np.zeros_like(ts))
        self.signals.data = (ts, *columns)
        self.error.data = (ts, f32(history["dcm_error"], every))


def live_controls(gui: viser.GuiApi, plot: LivePlot, on_window: Callable[[float], None]) -> dict:
    """The live plot's controls: axis, one checkbox per signal, the window (s)."""
    handles: dict = {}
    handles["axis"] = gui.add_dropdown("axis", AXES, initial_value=plot.axis)
    handles["axis"].on_update(lambda e: plot.set_axis(e.target.value))
    handles["window"] = gui.add_slider(
        "window [s]", min=1.0, max=60.0, step=1.0, initial_value=8.0,
        hint="How much of the time before the frame shown the plot spans (the buffer keeps 60 s)",
    )  # fmt: skip
    handles["window"].on_update(lambda e: on_window(float(e.target.value)))
    with gui.add_folder("signals", expand_by_default=True):
        for key, (label, _, _, _, shown) in LIVE_SIGNALS.items():
            box = gui.add_checkbox(
                {"com": "CoM x", "cop": "measured CoP"}.get(key, label),
                initial_value=shown,
                hint=SIGNALS[key].description if key in SIGNALS else "centre of pressure of "
                "the measured contact forces",
            )  # fmt: skip
            box.on_update(lambda e, k=key: plot.show(k, e.target.value))
            handles[key] = box
    return handles


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
        + f" · <span style='color:{GHOST_STROKE}'>┅</span> kept preview A"
        "</small>"
    )
