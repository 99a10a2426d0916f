"""Reporting a sweep's result: ratios to tracking, envelope metrics (weakest direction, mean,
area), text tables, envelope.json / envelope.csv and the polar plot envelope.png."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np

from dcmviz import GRAVITY


def ratios(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per direction: each controller's max impulse over tracking's."""
    by_dir: dict[float, dict[str, float]] = {}
    for r in rows:
        by_dir.setdefault(r["direction_deg"], {})[r["controller"]] = r["max_impulse_ns"]
    out = []
    for d in sorted(by_dir):
        row: dict[str, Any] = {"direction_deg": d}
        base = by_dir[d].get("tracking")
        for name, value in by_dir[d].items():
            if name != "tracking":
                row[f"{name}/tracking"] = value / base if base else None
        out.append(row)
    return out


METRICS = ("weakest", "mean", "area")


def envelope_metric(
    rows: list[dict[str, Any]], metric: str, controller: str | None = None
) -> float:
    """One number for an envelope (one controller's rows; ``controller`` None: all rows).

    ``weakest``: the smallest max impulse over the directions (N·s); ``mean``: their mean (N·s);
    ``area``: the area of the polar polygon through them, ½ Σ J_i J_{i+1} sin(θ_{i+1} − θ_i)
    ((N·s)², directions in order, closed).
    """
    mine = sorted(
        (r for r in rows if controller is None or r["controller"] == controller),
        key=lambda r: r["direction_deg"],
    )
    if not mine:
        raise ValueError(f"no envelope rows for controller {controller!r}")
    j = np.array([r["max_impulse_ns"] for r in mine], dtype=float)
    if metric == "weakest":
        return float(j.min())
    if metric == "mean":
        return float(j.mean())
    if metric == "area":
        theta = np.radians([r["direction_deg"] for r in mine])
        dtheta = (np.roll(theta, -1) - theta) % (2.0 * np.pi)
        if len(mine) == 1:
            return 0.0
        return float(0.5 * np.sum(j * np.roll(j, -1) * np.sin(dtheta)))
    raise ValueError(f"metric {metric!r}: allowed {', '.join(METRICS)}")


def _by_direction(result: dict[str, Any], key: str) -> list[tuple[str, float]]:
    """A bound of ``result`` (direction in degrees, keyed to 0.1 as
    experiments.stance_edge_bounds keys it → N·s) as (key, value) pairs by direction."""
    return sorted((result.get(key) or {}).items(), key=lambda x: float(x[0]))


def _listed(bound: list[tuple[str, float]]) -> str:
    return ", ".join(f"{float(d):.0f}° {v:.1f}" for d, v in bound) + " N·s"


def table(result: dict[str, Any]) -> str:
    """The envelope as a text table (impulses in N·s) with ratios to tracking."""
    names = result["settings"]["controllers"]
    rows = result["rows"]
    by_dir: dict[float, dict[str, dict]] = {}
    for r in rows:
        by_dir.setdefault(r["direction_deg"], {})[r["controller"]] = r
    head = f"{'dir °':>6} " + " ".join(f"{n:>25}" for n in names)
    ratio_names = [n for n in names if n != "tracking" and "tracking" in names]
    head += "".join(f" {n + '/trk':>28}" for n in ratio_names)
    lines = [
        f"max survived push impulse (N·s), {result['settings']['push_duration_s']} s pushes at "
        f"{result['push_start_s']:.3f} s ({result['settings']['phase']:.2f} of step "
        f"{result['settings']['step']}'s single support, {result['swing_side']} foot swinging), "
        "resolution "
        f"{result['resolution_ns']:.2f} N·s",
        head,
    ]
    for d in sorted(by_dir):
        cells = []
        for n in names:
            r = by_dir[d].get(n)
            mark = ("≥" if r["capped"] else "") + ("*" if r["non_monotone_ns"] else "")
            cells.append(f"{mark}{r['max_impulse_ns']:7.1f} ({r['max_force_n']:6.0f} N)".rjust(25))
        line = f"{d:6.1f} " + " ".join(cells)
        base = by_dir[d]["tracking"]["max_impulse_ns"] if "tracking" in names else None
        for n in ratio_names:
            v = by_dir[d][n]["max_impulse_ns"]
            line += f" {(v / base if base else float('nan')):28.2f}"
        lines.append(line)
    if any(r["non_monotone_ns"] for r in rows):
        lines.append("* survival is not monotone here: a larger grid impulse survived (see JSON)")
    if any(r["capped"] for r in rows):
        lines.append("≥ survived the whole bracket; raise --max-impulse")
    bound = _by_direction(result, "stance_edge_bound_ns")
    if bound:
        lines.append(
            "towards the stance foot no strategy without crossing steps that lifts the stance "
            "foot only with ξ back over it exceeds (CoP on the stance sole's edge from the "
            "push's start, a humanoid's feet also taking the push's moment about the CoM; "
            "dcmviz.sweep.bounds): " + _listed(bound)
        )
        if trunk := _by_direction(result, "stance_edge_bound_trunk_ns"):
            lines.append(
                "the same with the push's moment taken by the trunk as angular momentum (given "
                "back once ξ is caught) instead of by the feet: " + _listed(trunk)
            )
        if swung := _by_direction(result, "swing_bound_ns"):
            lines.append(
                "stepping the stance foot out once the other foot is down (the CoP on that sole "
                "while it swings, swings as the walker's: swing_bound_at) at most: "
                + _listed(swung)
            )
        if crossed := _by_direction(result, "crossover_bound_ns"):
            lines.append(
                "with a footstep across the stance foot (inside the robot's crossover region; a "
                "humanoid's at most its legs' reach past the CoM at the landing; "
                "dcmviz.sweep.bounds) at most: " + _listed(crossed)
            )
        reached_at = {f"{d:.1f}": cells for d, cells in by_dir.items()}
        for d, v in bound:
            if reached := reached_at.get(d):
                shares = (f"{n} {100 * reached[n]['max_impulse_ns'] / v:.0f} %" for n in names)
                lines.append(
                    f"  {float(d):.0f}°: " + ", ".join(shares) + " of the stance-edge bound"
                )
    lines.append(f"{len(rows)} cells in {result['wall_time_s']:.1f} s wall")
    return "\n".join(lines)


def write_envelope(result: dict[str, Any], out: Path) -> list[Path]:
    """envelope.json, envelope.csv and the polar plot envelope.png in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "envelope.json", out / "envelope.csv", out / "envelope.png"]
    paths[0].write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    with paths[1].open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["direction_deg", "controller", "max_impulse_ns", "max_force_n", "capped"])
        for r in result["rows"]:
            w.writerow(
                [
                    r["direction_deg"],
                    r["controller"],
                    f"{r['max_impulse_ns']:.3f}",
                    f"{r['max_force_n']:.2f}",
                    r["capped"],
                ]
            )
    plot_polar(result, paths[2])
    return paths


def plot_polar(result: dict[str, Any], path: Path, *, compact: bool = False) -> None:
    """One closed curve per controller: max impulse (N·s) against push direction, and the
    stance-edge bound the report's table prints (black diamonds, where the result has it; grey
    ones: the same bound with the push's moment taken by the trunk; black crosses: the swing
    bound, the stance foot stepping out once the other is down).

    ``compact``: a short title in a larger font, for a plot shown a few hundred pixels wide
    (the dashboard's Sweep tab); the long one's details are in the table and the JSON."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(6.4, 6.4))
    ax = fig.add_subplot(projection="polar")
    styles = {
        "tracking": "o-", "step_adjustment": "s-", "step_adjustment+observer": "^--",
        "next_step": "s-", "multi_step": "d-", "multi_step_timing": "^-", "crossover": "*-",
    }  # fmt: skip
    for name in result["settings"]["controllers"]:
        rows = sorted(
            (r for r in result["rows"] if r["controller"] == name),
            key=lambda r: r["direction_deg"],
        )
        theta = np.radians([r["direction_deg"] for r in rows])
        radius = np.array([r["max_impulse_ns"] for r in rows])
        theta, radius = np.append(theta, theta[:1]), np.append(radius, radius[:1])
        ax.plot(theta, radius, styles.get(name, "-"), label=name, lw=1.8, ms=5)
    for key, style, color, label in (
        ("stance_edge_bound_ns", "D", "k", "stance-edge bound"),
        ("stance_edge_bound_trunk_ns", "D", "0.55", "the same, moment taken by the trunk"),
        ("swing_bound_ns", "X", "k", "stance foot stepping out, walker's swings"),
    ):
        if points := _by_direction(result, key):
            ax.plot(
                np.radians([float(d) for d, _ in points]), [v for _, v in points], style,
                color=color, ms=7, mfc="none", mew=1.6, label=label,
            )  # fmt: skip
    ax.set_theta_zero_location("E")  # 0° = +x forward, counter-clockwise = toward +y (left)
    if compact:
        ax.set_title(
            f"max push impulse [N·s], {result['robot']}\n0° forward, 90° left", fontsize=15
        )
        ax.tick_params(labelsize=12)
        ax.legend(loc="lower left", bbox_to_anchor=(-0.15, -0.17), fontsize=12)
    else:
        ax.set_title(
            f"{result['preset']} ({result['robot']}, {result['backend']}): max push impulse "
            f"(N·s)\n{result['settings']['push_duration_s']} s push at "
            f"{result['settings']['phase']:.0%} of step {result['settings']['step']}'s single "
            f"support ({result['swing_side']} foot swinging); 0° = forward, 90° = left",
            fontsize=9,
        )
        ax.legend(loc="lower left", bbox_to_anchor=(-0.12, -0.12), fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def ramp_table(result: dict[str, Any]) -> str:
    """The ramp test as a text table: max held force per controller (N and % of weight)."""
    p = result["push"]
    lines = [
        f"ramped push ({p['ramp']} s ramp, held to {p['start'] + p['duration']:.1f} s, "
        f"direction {np.round(np.array(p['force']) / result['preset_force_n'], 3).tolist()}); "
        f"preset force {result['preset_force_n']:.0f} N "
        f"({100 * result['preset_force_n'] / (result['mass_kg'] * GRAVITY):.1f} % of weight)",
        f"{'controller':>26} {'max held force':>16} {'% weight':>9} {'falls at':>10}",
    ]
    for r in result["rows"]:
        fail = r["first_fall_force_n"]
        held = ("≥" if r["capped"] else "") + f"{r['max_held_force_n']:.1f} N"
        lines.append(
            f"{r['controller']:>26} {held:>16}"
            f" {r['max_held_force_pct_weight']:8.1f}% "
            + (f"{fail:9.1f} N" if fail is not None else "     never")
            + (" (non-monotone)" if r["non_monotone_n"] else "")
        )
    lines.append(f"in {result['wall_time_s']:.1f} s wall")
    return "\n".join(lines)
