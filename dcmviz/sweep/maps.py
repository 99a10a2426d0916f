"""Gain maps: the push-recovery envelope over a grid of two preset keys
(``--grid control.k_xi=1:6:6 dcm.b=0.28:0.32:3``), reduced to one number per point (the weakest
direction's impulse, or ``--metric``), as a heatmap with the preset's own values marked, and CSV.

All points' envelope searches run as one sweep (:func:`~dcmviz.sweep.scheduler.run_cells`), so the
rollouts of every point and direction share the workers.
"""

from __future__ import annotations

import csv
import itertools
import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dcmviz.config import Config, ConfigError, config_from_dict
from dcmviz.sweep.experiments import (
    PRESET_CONTROLLER,
    Execution,
    SweepSettings,
    envelope_cells,
    envelope_row,
    run,
)
from dcmviz.sweep.report import METRICS, envelope_metric

METRIC_UNITS = {"weakest": "N·s", "mean": "N·s", "area": "(N·s)²"}


@dataclass(frozen=True)
class Axis:
    """One map axis: a preset key (``section.name``) and its values."""

    key: str
    values: tuple[float, ...]

    @property
    def section(self) -> str:
        return self.key.split(".")[0]

    @property
    def name(self) -> str:
        return self.key.split(".")[1]


def parse_axis(text: str, config: Config) -> Axis:
    """``section.key=start:stop:count`` → evenly spaced values (count ≥ 1); the key must be a
    number in the preset."""
    key, sep, spec = text.partition("=")
    key = key.strip()
    form = "section.key=start:stop:count, e.g. control.k_xi=1:6:6"
    if not sep:
        raise ValueError(f"--grid {text!r}: expected {form} (the coarse grid size is --coarse)")
    parts = key.split(".")
    data = config.to_dict()
    if len(parts) != 2 or not isinstance(data.get(parts[0]), dict):
        sections = [k for k, v in data.items() if isinstance(v, dict)]
        raise ValueError(f"--grid {text!r}: the key must be section.key with section in {sections}")
    section, name = parts
    current = data[section].get(name)
    if isinstance(current, bool) or not isinstance(current, int | float):
        numeric = [k for k, v in data[section].items() if type(v) in (int, float)]
        raise ValueError(
            f"--grid {text!r}: {key} is not a number key; numbers in [{section}]: {numeric}"
        )
    try:
        start_s, stop_s, count_s = spec.split(":")
        start, stop, count = float(start_s), float(stop_s), int(count_s)
    except ValueError:
        raise ValueError(f"--grid {text!r}: expected {form}") from None
    if count < 1 or not (math.isfinite(start) and math.isfinite(stop)):
        raise ValueError(f"--grid {text!r}: start and stop must be finite and count ≥ 1")
    values = [float(f"{v:.12g}") for v in np.linspace(start, stop, count)]
    if type(current) is int:
        if any(v != round(v) for v in values):
            raise ValueError(f"--grid {text!r}: {key} takes integers, got {values}")
        values = [int(round(v)) for v in values]
    return Axis(key, tuple(values))


def point_config(config: Config, axes: list[Axis], point: tuple[float, ...]) -> Config:
    """The preset with the axes' keys set to ``point``; ConfigError names a bad key and value."""
    data = config.to_dict()
    for axis, value in zip(axes, point, strict=True):
        data[axis.section][axis.name] = value
    try:
        return config_from_dict(data)
    except ConfigError as err:
        where = ", ".join(f"{a.key}={v}" for a, v in zip(axes, point, strict=True))
        raise ConfigError(f"--grid point {where}: {err}") from None


def gain_map(
    config: Config,
    axes: list[Axis],
    settings: SweepSettings,
    *,
    metric: str = "weakest",
    execution: Execution | None = None,
) -> dict[str, Any]:
    """Envelope metric at every grid point (C order: the last axis varies fastest)."""
    if not 1 <= len(axes) <= 2:
        raise ValueError(f"--grid: give one or two keys, got {len(axes)}")
    if metric not in METRICS:
        raise ValueError(f"--metric {metric!r}: allowed {', '.join(METRICS)}")
    points = list(itertools.product(*(a.values for a in axes)))
    configs = [point_config(config, axes, p) for p in points]  # all validated before running
    cells = []
    for i, (p, cfg) in enumerate(zip(points, configs, strict=True)):
        label = {"point": i, **{a.key: v for a, v in zip(axes, p, strict=True)}}
        cells += envelope_cells(cfg, settings, label)[0]
    sweep = run(cells, settings, execution, "map")
    rows = [envelope_row(o) for o in sweep.outcomes]
    values = []
    for i, p in enumerate(points):
        mine = [r for r in rows if r["point"] == i]
        for name in settings.controllers:
            entry = {a.key: v for a, v in zip(axes, p, strict=True)}
            entry["controller"] = name
            for m in METRICS:
                entry[m] = envelope_metric(mine, m, name)
            values.append(entry)
    return {
        "preset": config.name,
        "robot": config.robot.model,
        "backend": settings.backend,
        "axes": [{"key": a.key, "values": list(a.values)} for a in axes],
        "preset_point": [_get(config, a) for a in axes],
        "metric": metric,
        "settings": asdict(settings),
        "resolution_ns": settings.max_impulse_ns / settings.grid / 2**settings.iterations,
        "wall_time_s": sweep.wall_time_s,
        "rollouts": {"run": sweep.run, "from_store": sweep.cached, "runner": sweep.runner},
        "values": values,
        "rows": rows,
    }


def _get(config: Config, axis: Axis) -> float:
    return getattr(getattr(config, axis.section), axis.name)


def map_grid(result: dict[str, Any], controller: str, metric: str) -> np.ndarray:
    """The metric of one controller as an array shaped like the axes."""
    shape = [len(a["values"]) for a in result["axes"]]
    v = [e[metric] for e in result["values"] if e["controller"] == controller]
    return np.array(v, dtype=float).reshape(shape)


def write_map(result: dict[str, Any], out: Path) -> list[Path]:
    """map.json, map.csv (one row per point and controller) and the heatmap map.png."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "map.json", out / "map.csv", out / "map.png"]
    paths[0].write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    keys = [a["key"] for a in result["axes"]]
    with paths[1].open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow([*keys, "controller", "weakest_ns", "mean_ns", "area_ns2"])
        for e in result["values"]:
            w.writerow(
                [*(e[k] for k in keys), e["controller"]]
                + [f"{e['weakest']:.3f}", f"{e['mean']:.3f}", f"{e['area']:.1f}"]
            )
    plot_map(result, paths[2])
    return paths


def plot_map(result: dict[str, Any], path: Path) -> None:
    """One heatmap per controller; cell text is the metric, ★ marks the preset's own values."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    axes = result["axes"]
    point = list(result["preset_point"])
    if len(axes) == 1:  # a single row
        axes = [axes[0], {"key": "", "values": [0]}]
        point.append(0)
    names = result["settings"]["controllers"]
    metric = result["metric"]
    fig, panels = plt.subplots(1, len(names), figsize=(1.2 + 4.8 * len(names), 4.4), squeeze=False)
    for ax, name in zip(panels[0], names, strict=True):
        # first key along x, second along y
        grid = map_grid(result, name, metric).reshape(len(axes[0]["values"]), -1).T
        im = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis")
        fig.colorbar(im, ax=ax, label=f"{metric} ({METRIC_UNITS[metric]})")
        for (r, c), v in np.ndenumerate(grid):
            ax.text(c, r, f"{v:.3g}", ha="center", va="center", fontsize=7, color="w")
        xs, ys = axes[0]["values"], axes[1]["values"]
        ax.set_xticks(range(len(xs)), [f"{v:g}" for v in xs])
        ax.set_yticks(range(len(ys)), [f"{v:g}" for v in ys] if axes[1]["key"] else [""])
        ax.set_xlabel(axes[0]["key"])
        ax.set_ylabel(axes[1]["key"])
        ix, iy = _index(xs, point[0]), _index(ys, point[1])
        ax.plot(ix, iy, marker="*", ms=16, mfc="red", mec="white", ls="none", label="preset")
        ax.legend(loc="upper right", fontsize=7)
        title = "preset controller" if name == PRESET_CONTROLLER else name
        ax.set_title(title, fontsize=9)
    n_dir = len({r["direction_deg"] for r in result["rows"]})
    fig.suptitle(
        f"{result['preset']} ({result['robot']}, {result['backend']}): {metric} push impulse "
        f"over {n_dir} directions",
        fontsize=10,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _index(values: list[float], v: float) -> float:
    """Fractional index of value v on an evenly spaced axis (extrapolated outside it)."""
    if len(values) == 1:
        return 0.0
    return (v - values[0]) / (values[-1] - values[0]) * (len(values) - 1)
